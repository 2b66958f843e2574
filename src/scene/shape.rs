//! An object's shape as a scene names it ([`ObjectShape`]): parsed when the scene is read, so a
//! malformed shape is refused at load with its line and column.

use crate::geometry::{GeometryError, ShapeSpec};
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::path::{Path, PathBuf};

/// What an object's shape names.
#[derive(Debug, Clone, PartialEq)]
pub enum ShapeSource {
    /// A primitive or a shape file (`box:LX,LY,LZ`, `sphere:R`, a mesh, point-cloud, splat or
    /// NIfTI file; a relative path is relative to the scene file).
    Spec(ShapeSpec),
    /// `image`: the filled voxels of the object's `[object.image]` table's image.
    Image,
    /// An object made from arrays ([`super::World::with_objects`]): there is no shape to read,
    /// and the text only names the object's origin in reports (`numpy points`).
    Arrays,
}

/// An object's shape: what it names, parsed, with the text it was written as (reports show
/// that text, and the basis cache key of a primitive is made from it).
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectShape {
    text: String,
    source: ShapeSource,
}

impl ObjectShape {
    /// Parse a scene's `shape`: `box:LX,LY,LZ`, `sphere:R` (metres), a path to a shape file,
    /// or `image`.
    ///
    /// # Errors
    /// [`ShapeSpec::parse`]'s ([`GeometryError::BadPrimitive`], [`GeometryError::UnknownSpec`]).
    pub fn parse(text: &str) -> Result<ObjectShape, GeometryError> {
        let source = if text.trim() == "image" {
            ShapeSource::Image
        } else {
            ShapeSource::Spec(ShapeSpec::parse(text)?)
        };
        Ok(ObjectShape {
            text: text.to_string(),
            source,
        })
    }

    /// The shape of an object made from arrays, named `description` in reports.
    pub fn arrays(description: &str) -> ObjectShape {
        ObjectShape {
            text: description.to_string(),
            source: ShapeSource::Arrays,
        }
    }

    /// The text as written (the scene file's, or the description of an object from arrays).
    pub fn text(&self) -> &str {
        &self.text
    }

    /// What it names.
    pub fn source(&self) -> &ShapeSource {
        &self.source
    }

    /// The shape file or image it names, with a relative path resolved against `base`
    /// (None for primitives, `image` and objects from arrays).
    pub fn file(&self, base: &Path) -> Option<PathBuf> {
        match &self.source {
            ShapeSource::Spec(spec) => spec.resolved(base).path().map(Path::to_path_buf),
            ShapeSource::Image | ShapeSource::Arrays => None,
        }
    }
}

impl std::str::FromStr for ObjectShape {
    type Err = GeometryError;

    fn from_str(text: &str) -> Result<ObjectShape, GeometryError> {
        ObjectShape::parse(text)
    }
}

impl Serialize for ObjectShape {
    /// The text as written.
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(&self.text)
    }
}

impl<'de> Deserialize<'de> for ObjectShape {
    /// Parsed from its text: a malformed shape is an error of the scene file.
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<ObjectShape, D::Error> {
        let text = String::deserialize(deserializer)?;
        ObjectShape::parse(&text).map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shapes_parse_and_keep_their_text() {
        let b = ObjectShape::parse("box:1, 0.5,2").unwrap();
        assert_eq!(b.text(), "box:1, 0.5,2");
        assert_eq!(
            b.source(),
            &ShapeSource::Spec(ShapeSpec::Box {
                size: [1.0, 0.5, 2.0]
            })
        );
        assert_eq!(b.file(Path::new("/scenes")), None);
        let m = ObjectShape::parse(" data/ell.obj").unwrap();
        assert_eq!(
            m.file(Path::new("/scenes")),
            Some(PathBuf::from("/scenes/data/ell.obj"))
        );
        assert_eq!(
            ObjectShape::parse("image").unwrap().source(),
            &ShapeSource::Image
        );
        assert_eq!(ObjectShape::arrays("numpy points").text(), "numpy points");
        for bad in ["box:1,1", "sphere:-1", "ball", "mesh.xyz", ""] {
            assert!(ObjectShape::parse(bad).is_err(), "{bad}");
        }
    }
}
