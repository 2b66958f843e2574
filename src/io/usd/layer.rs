//! A USD layer built in memory (written as usda by [`super::write_usda`]): prims defined in
//! order, typed attributes with a default value and/or time samples, applied API schemas.
//! Values are kept in the types they are written in (f32 for points, as USD stores them), so
//! a run's frames are held once.

use crate::geometry::UpAxis;
use std::collections::HashMap;

/// One attribute value, in the type it is written as.
#[derive(Debug, Clone, PartialEq)]
pub enum UsdValue {
    /// `int`.
    Int(i32),
    /// `float`.
    Float(f32),
    /// `double`.
    Double(f64),
    /// `token`.
    Token(String),
    /// `token[]`.
    Tokens(Vec<String>),
    /// `int[]`.
    Ints(Vec<i32>),
    /// `float[]`.
    Floats(Vec<f32>),
    /// `point3f[]`, `float3[]`, `vector3f[]`, ...: N x 3.
    Float3s(Vec<[f32; 3]>),
    /// `quatf[]`: N unit quaternions (w, x, y, z).
    Quats(Vec<[f32; 4]>),
    /// `matrix4d`: row-major, row-vector convention (translation in the last row), as USD.
    Matrix4(Box<[f64; 16]>),
}

impl UsdValue {
    /// Number of array elements (1 for a scalar).
    pub fn len(&self) -> usize {
        match self {
            UsdValue::Ints(v) => v.len(),
            UsdValue::Tokens(v) => v.len(),
            UsdValue::Floats(v) => v.len(),
            UsdValue::Float3s(v) => v.len(),
            UsdValue::Quats(v) => v.len(),
            _ => 1,
        }
    }

    /// True for an empty array.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// An attribute of a prim: its USD type name, variability, default value, time samples and
/// metadata.
#[derive(Debug, Clone)]
pub(super) struct Attribute {
    pub(super) name: String,
    pub(super) type_name: String,
    pub(super) uniform: bool,
    pub(super) default: Option<UsdValue>,
    pub(super) samples: Vec<(f64, UsdValue)>,
    pub(super) interpolation: Option<&'static str>,
    pub(super) element_size: Option<i32>,
}

#[derive(Debug, Clone)]
pub(super) struct Prim {
    pub(super) path: String,
    pub(super) type_name: String,
    pub(super) api_schemas: Vec<String>,
    pub(super) children: Vec<String>,
    pub(super) attributes: Vec<Attribute>,
}

/// Stage metadata written on the layer.
#[derive(Debug, Clone, PartialEq)]
pub struct StageMetadata {
    /// `timeCodesPerSecond` (and `framesPerSecond`): 1 / dt for a run. None: not written.
    pub time_codes_per_second: Option<f64>,
    /// `startTimeCode` and `endTimeCode`. None: not written.
    pub time_range: Option<(f64, f64)>,
    /// `upAxis`.
    pub up_axis: UpAxis,
    /// `metersPerUnit` (freeform writes metres: 1).
    pub meters_per_unit: f64,
    /// `doc` of the layer.
    pub documentation: String,
}

/// A USD layer under construction: a prim tree with `/World` (an `Xform`, the default prim)
/// at its root.
#[derive(Debug, Clone)]
pub struct UsdLayer {
    /// Metadata; the time range can be set when the last frame is known.
    pub metadata: StageMetadata,
    prims: Vec<Prim>,
    index: HashMap<String, usize>,
}

/// The root prim every layer has.
pub const WORLD: &str = "/World";

impl UsdLayer {
    /// A layer holding only `/World`.
    pub fn new(metadata: StageMetadata) -> UsdLayer {
        let mut layer = UsdLayer {
            metadata,
            prims: Vec::new(),
            index: HashMap::new(),
        };
        layer.push_prim(WORLD, "Xform");
        layer
    }

    fn push_prim(&mut self, path: &str, type_name: &str) {
        self.index.insert(path.to_string(), self.prims.len());
        self.prims.push(Prim {
            path: path.to_string(),
            type_name: type_name.to_string(),
            api_schemas: Vec::new(),
            children: Vec::new(),
            attributes: Vec::new(),
        });
    }

    /// Define prim `name` of type `type_name` under `parent` (which must exist); its path.
    /// Names must be valid and unique among their siblings ([`super::unique_prim_name`]).
    pub fn define(&mut self, parent: &str, name: &str, type_name: &str) -> String {
        let path = format!("{parent}/{name}");
        let p = self.index[parent];
        debug_assert!(!self.prims[p].children.iter().any(|c| c == name));
        self.prims[p].children.push(name.to_string());
        self.push_prim(&path, type_name);
        path
    }

    /// Whether a prim exists at `path`.
    pub fn has_prim(&self, path: &str) -> bool {
        self.index.contains_key(path)
    }

    /// Apply API schema `schema` (e.g. `KaolinSkinnedPhysicsAPI:default`) to the prim.
    pub fn apply_api(&mut self, prim: &str, schema: &str) {
        let p = self.index[prim];
        self.prims[p].api_schemas.push(schema.to_string());
    }

    fn attribute(&mut self, prim: &str, name: &str, type_name: &str) -> &mut Attribute {
        let p = self.index[prim];
        let attrs = &mut self.prims[p].attributes;
        let i = match attrs.iter().position(|a| a.name == name) {
            Some(i) => i,
            None => {
                attrs.push(Attribute {
                    name: name.to_string(),
                    type_name: type_name.to_string(),
                    uniform: false,
                    default: None,
                    samples: Vec::new(),
                    interpolation: None,
                    element_size: None,
                });
                attrs.len() - 1
            }
        };
        &mut attrs[i]
    }

    /// Set the default value of attribute `name` (USD type `type_name`) of `prim`.
    pub fn set(&mut self, prim: &str, name: &str, type_name: &str, value: UsdValue) {
        self.attribute(prim, name, type_name).default = Some(value);
    }

    /// As [`Self::set`], declared `uniform` (not animatable).
    pub fn set_uniform(&mut self, prim: &str, name: &str, type_name: &str, value: UsdValue) {
        let a = self.attribute(prim, name, type_name);
        a.uniform = true;
        a.default = Some(value);
    }

    /// Add a time sample of attribute `name` at time code `time` (ascending across calls).
    pub fn push_sample(&mut self, prim: &str, name: &str, type_name: &str, time: f64, v: UsdValue) {
        self.attribute(prim, name, type_name)
            .samples
            .push((time, v));
    }

    /// Declare attribute `name` a primvar's `interpolation` (`vertex`, `constant`, ...) and,
    /// for arrays of several values per element, its `elementSize`.
    pub fn primvar_metadata(
        &mut self,
        prim: &str,
        name: &str,
        type_name: &str,
        interpolation: &'static str,
        element_size: Option<i32>,
    ) {
        let a = self.attribute(prim, name, type_name);
        a.interpolation = Some(interpolation);
        a.element_size = element_size;
    }

    /// The prim at `path`, if defined.
    pub(super) fn prim_at(&self, path: &str) -> Option<&Prim> {
        self.index.get(path).map(|&i| &self.prims[i])
    }

    /// Declare attribute `name`'s `elementSize` (values per element of an array).
    pub fn element_size(&mut self, prim: &str, name: &str, type_name: &str, n: i32) {
        self.attribute(prim, name, type_name).element_size = Some(n);
    }

    /// Number of time samples of attribute `name` of `prim` (0 if absent).
    pub fn sample_count(&self, prim: &str, name: &str) -> usize {
        self.index
            .get(prim)
            .and_then(|&p| self.prims[p].attributes.iter().find(|a| a.name == name))
            .map_or(0, |a| a.samples.len())
    }
}
