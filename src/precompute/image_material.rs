//! Materials from a voxel image: each integration point takes the material of the voxel whose
//! centre is nearest ([`VoxelImage::voxel_at`]): a label's material from the label map, or a
//! modulus voxel's Young's modulus with the object's Poisson ratio and density.
//!
//! Nearest-voxel lookup is piecewise constant, like the image itself: no interpolation across
//! a material interface, so a stiff inclusion keeps its modulus up to its voxels' faces.

use crate::geometry::{GeometryError, VoxelImage, VoxelValues};
use crate::material::{Material, MaterialField};
use crate::{Point3, Result};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;
use std::sync::Arc;

/// What a point inside the object gets when it falls outside the image or in an empty voxel
/// (possible when a mesh or primitive is the shape and the image only gives materials).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GapPolicy {
    /// Refuse with [`GeometryError::MaterialGap`] naming the point (default: a gap is usually
    /// a misregistered image).
    #[default]
    Error,
    /// Give such points the object's own material.
    Material,
}

/// A voxel image with its label map: the material source of an object.
#[derive(Debug, Clone)]
pub struct ImageMaterial {
    image: Arc<VoxelImage>,
    labels: BTreeMap<i64, Material>,
    gaps: GapPolicy,
    /// SHA-256 of the image's grid and values (hex), so cache keys follow the content.
    digest: String,
}

impl PartialEq for ImageMaterial {
    fn eq(&self, other: &Self) -> bool {
        self.digest == other.digest && self.labels == other.labels && self.gaps == other.gaps
    }
}

/// What an [`ImageMaterial`] contributes to serialized basis options (cache keys, metadata).
#[derive(Serialize)]
struct Key<'a> {
    image_sha256: &'a str,
    labels: Vec<(i64, Material)>,
    gaps: GapPolicy,
}

impl Serialize for ImageMaterial {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        Key {
            image_sha256: &self.digest,
            labels: self.labels.iter().map(|(k, v)| (*k, *v)).collect(),
            gaps: self.gaps,
        }
        .serialize(s)
    }
}

impl ImageMaterial {
    /// Materials from `image`: `labels` maps label values to materials (label images; must
    /// name every label a filled voxel holds, and may map 0 to fill empty voxels); a modulus
    /// image takes no labels. `gaps` says what points outside the filled voxels get.
    ///
    /// # Errors
    /// [`GeometryError::UnknownLabel`] naming a label without material and the first voxel
    /// holding it; [`crate::Error::InvalidParameter`] for labels given to a modulus image or an
    /// invalid material.
    pub fn new(
        image: Arc<VoxelImage>,
        labels: BTreeMap<i64, Material>,
        gaps: GapPolicy,
    ) -> Result<Self> {
        for (label, m) in &labels {
            m.validate().map_err(|e| {
                crate::Error::param("image.labels", label, format!("its material: {e}"))
            })?;
        }
        match image.values() {
            VoxelValues::Labels(v) => {
                if let Some(n) = v.iter().position(|l| *l != 0 && !labels.contains_key(l)) {
                    return Err(GeometryError::UnknownLabel {
                        label: v[n],
                        voxel: image.ijk(n),
                    }
                    .into());
                }
            }
            VoxelValues::Moduli(_) if !labels.is_empty() => {
                return Err(crate::Error::param(
                    "image.labels",
                    format!("{} label(s)", labels.len()),
                    "a modulus image gives Young's modulus per voxel (with the object's Poisson \
                     ratio and density); labels apply to label images only",
                ))
            }
            VoxelValues::Moduli(_) => {}
        }
        let digest = digest(&image);
        Ok(Self {
            image,
            labels,
            gaps,
            digest,
        })
    }

    /// The image.
    pub fn image(&self) -> &Arc<VoxelImage> {
        &self.image
    }

    /// The same materials with another gap policy.
    pub fn with_gaps(&self, gaps: GapPolicy) -> Self {
        Self {
            gaps,
            ..self.clone()
        }
    }

    /// The material at each of `points` (N x 3, metres): the nearest voxel's; `base` gives
    /// Poisson ratio and density for modulus voxels, and the material of gaps under
    /// [`GapPolicy::Material`].
    ///
    /// # Errors
    /// [`GeometryError::MaterialGap`] for the first point outside the image or in an empty
    /// voxel with no material for label 0 (under [`GapPolicy::Error`]); an invalid `base`.
    pub fn field(&self, points: &[Point3], base: &Material) -> Result<MaterialField> {
        base.validate()?;
        let img = &self.image;
        let at: Vec<Option<Material>> = points
            .par_iter()
            .map(|x| {
                let n = img.voxel_at(x)?;
                match img.values() {
                    VoxelValues::Labels(l) => self.labels.get(&l[n]).copied(),
                    VoxelValues::Moduli(e) => (e[n] > 0.0).then_some(Material {
                        youngs: e[n],
                        ..*base
                    }),
                }
            })
            .collect();
        let mut f = MaterialField::homogeneous(points.len(), base)?;
        for (i, m) in at.into_iter().enumerate() {
            match (m, self.gaps) {
                (Some(m), _) => {
                    f.youngs[i] = m.youngs;
                    f.poisson[i] = m.poisson;
                    f.density[i] = m.density;
                }
                (None, GapPolicy::Material) => {}
                (None, GapPolicy::Error) => {
                    let where_ = match img.voxel_at(&points[i]) {
                        Some(n) => format!("falls in empty voxel {:?}", img.ijk(n)),
                        None => "is outside the image".to_string(),
                    };
                    return Err(GeometryError::MaterialGap {
                        point: i,
                        position: points[i],
                        where_,
                    }
                    .into());
                }
            }
        }
        Ok(f)
    }
}

/// Hex SHA-256 of an image's dimensions, spacing, origin, value kind and values.
fn digest(image: &VoxelImage) -> String {
    let mut h = Sha256::new();
    for d in image.dims() {
        h.update((d as u64).to_le_bytes());
    }
    for v in image.spacing().iter().chain(image.origin().iter()) {
        h.update(v.to_le_bytes());
    }
    match image.values() {
        VoxelValues::Labels(v) => {
            h.update(b"labels");
            for chunk in v.chunks(1 << 16) {
                let bytes: Vec<u8> = chunk.iter().flat_map(|x| x.to_le_bytes()).collect();
                h.update(&bytes);
            }
        }
        VoxelValues::Moduli(v) => {
            h.update(b"moduli");
            for chunk in v.chunks(1 << 16) {
                let bytes: Vec<u8> = chunk.iter().flat_map(|x| x.to_le_bytes()).collect();
                h.update(&bytes);
            }
        }
    }
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two_labels() -> Arc<VoxelImage> {
        // 2 x 1 x 1 voxels of 1 m centred at x = 0.5 and 1.5: labels 1 and 2.
        Arc::new(
            VoxelImage::new(
                [2, 1, 1],
                [1.0; 3],
                [0.5, 0.5, 0.5],
                VoxelValues::Labels(vec![1, 2]),
            )
            .unwrap(),
        )
    }

    fn mat(e: f64) -> Material {
        Material {
            youngs: e,
            ..Material::default()
        }
    }

    #[test]
    fn labels_give_their_materials_and_gaps_are_named() {
        let map = BTreeMap::from([(1, mat(1e9)), (2, mat(1e5))]);
        let im = ImageMaterial::new(two_labels(), map.clone(), GapPolicy::Error).unwrap();
        let f = im
            .field(&[[0.2, 0.5, 0.5], [1.9, 0.1, 0.9]], &mat(7.0))
            .unwrap();
        assert_eq!(f.youngs, vec![1e9, 1e5]);
        // Outside the image: a named gap, or the base material under GapPolicy::Material.
        let e = im
            .field(&[[0.5; 3], [2.5, 0.5, 0.5]], &mat(7.0))
            .unwrap_err();
        assert!(e.to_string().contains("integration point 1"), "{e}");
        assert!(e.to_string().contains("outside the image"), "{e}");
        let f = im
            .with_gaps(GapPolicy::Material)
            .field(&[[2.5, 0.5, 0.5]], &mat(7.0))
            .unwrap();
        assert_eq!(f.youngs, vec![7.0]);
        // A label the map does not name.
        let e = ImageMaterial::new(
            two_labels(),
            BTreeMap::from([(1, mat(1.0))]),
            GapPolicy::Error,
        )
        .unwrap_err();
        assert!(
            e.to_string().contains("label 2 (first at voxel [1, 0, 0])"),
            "{e}"
        );
    }

    #[test]
    fn serialized_key_follows_the_image_content_and_the_map() {
        let map = BTreeMap::from([(1, mat(1e9)), (2, mat(1e5))]);
        let key = |img: Arc<VoxelImage>, map: &BTreeMap<i64, Material>| {
            serde_json::to_string(&ImageMaterial::new(img, map.clone(), GapPolicy::Error).unwrap())
                .unwrap()
        };
        let a = key(two_labels(), &map);
        // The same content read again: the same key (the cache is reused).
        assert_eq!(a, key(two_labels(), &map));
        // One voxel changed, the grid moved, or the map changed: another key.
        let swapped = Arc::new(
            VoxelImage::new(
                [2, 1, 1],
                [1.0; 3],
                [0.5, 0.5, 0.5],
                VoxelValues::Labels(vec![2, 1]),
            )
            .unwrap(),
        );
        assert_ne!(a, key(swapped, &map));
        let moved = Arc::new(
            VoxelImage::new(
                [2, 1, 1],
                [1.0; 3],
                [0.5, 0.5, 0.75],
                VoxelValues::Labels(vec![1, 2]),
            )
            .unwrap(),
        );
        assert_ne!(a, key(moved, &map));
        let other_map = BTreeMap::from([(1, mat(1e9)), (2, mat(2e5))]);
        assert_ne!(a, key(two_labels(), &other_map));
    }

    #[test]
    fn moduli_keep_the_objects_poisson_and_density() {
        let img = Arc::new(
            VoxelImage::new(
                [2, 1, 1],
                [1.0; 3],
                [0.0; 3],
                VoxelValues::Moduli(vec![0.0, 3e4]),
            )
            .unwrap(),
        );
        let base = Material {
            youngs: 1.0,
            poisson: 0.3,
            density: 500.0,
        };
        let im = ImageMaterial::new(img.clone(), BTreeMap::new(), GapPolicy::Error).unwrap();
        let f = im.field(&[[1.0, 0.0, 0.0]], &base).unwrap();
        assert_eq!((f.youngs[0], f.poisson[0], f.density[0]), (3e4, 0.3, 500.0));
        let e = im.field(&[[0.0; 3]], &base).unwrap_err();
        assert!(e.to_string().contains("empty voxel [0, 0, 0]"), "{e}");
        assert!(ImageMaterial::new(img, BTreeMap::from([(1, base)]), GapPolicy::Error).is_err());
    }
}
