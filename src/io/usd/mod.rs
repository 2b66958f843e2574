//! USD stages (docs/usd.md): a run written as one time-sampled usda stage (`UsdLayer`,
//! filled by the scene's USD frame writer, written by `write_usda`), Kaolin's physics schemas
//! ([`kaolin`]), and prims read as shapes ([`read_usd_geometry`], [`read_usd_shape`]).

mod frames;
pub mod kaolin;
mod layer;
mod names;
mod read;
mod usda;

pub use frames::{
    read_usd_object, read_usd_splat_object, read_usd_splats, usd_stage_frames, UsdSplats,
    UsdStageFrames,
};
pub(crate) use layer::{StageMetadata, UsdLayer, UsdValue, WORLD};
pub(crate) use names::unique_prim_name;
pub use read::{
    read_usd_geometry, read_usd_shape, UsdGeometry, UsdPrimKind, UsdStage, FALLBACK_METERS_PER_UNIT,
};
pub(crate) use usda::write_usda;
