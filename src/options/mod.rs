//! The option table's names: every basis and eigensolver option once, with its name in the
//! library, on the command line, in scene files, in Python and in C ([`OptionName`]), and the
//! front end a message is written for ([`Front`]).
//!
//! Library messages never spell a flag or a key: they name an option through its row
//! (`format!("raise {}", options::TOL)`, or `options::SOLVER.with("lobpcg")` for advice with
//! a value), and the text follows the front end of the thread that formats it
//! ([`Front::scope`]: `freeform modes` prints `--tol`, `freeform run` `basis.eigen_tol`,
//! Python `tol`, a Rust caller `BasisOptions::tol`). What each option does, its default and how
//! each front end sets it is `precompute::table`, which points at these rows.
//!
//! A leaf: it imports nothing, so every stage (the eigensolvers included) can name options.
//! Where a new option goes: docs/architecture.md.

mod front;
mod name;

pub use front::Front;
pub use name::{OptionName, Setting};

/// Number of RKPM kernels K.
pub static KERNELS: OptionName = OptionName {
    library: "BasisOptions::kernels",
    flag: Some("--kernels"),
    scene: Some("basis.kernels"),
    python: Some("kernels"),
    c: Some("kernels"),
    value_prefix: "",
    help: "Number of RKPM kernels K",
};

/// Number of non-constant modes m.
pub static MODES: OptionName = OptionName {
    library: "BasisOptions::modes",
    flag: Some("--modes"),
    scene: Some("basis.modes"),
    python: Some("modes"),
    c: Some("modes"),
    value_prefix: "",
    help: "Number of non-constant modes m (m + 1 handles are computed)",
};

/// Integration points, a count.
pub static POINTS: OptionName = OptionName {
    library: "Resolution::Count",
    flag: Some("--points"),
    scene: Some("basis.points"),
    python: Some("points"),
    c: None,
    value_prefix: "",
    help: "Target number of integration points [default: 50 K, clamped to 20,000..2,000,000, \
           and 10 K above K = 200,000]",
};

/// Integration grid spacing, metres.
pub static SPACING: OptionName = OptionName {
    library: "Resolution::Spacing",
    flag: Some("--spacing"),
    scene: Some("basis.spacing"),
    python: Some("spacing"),
    c: None,
    value_prefix: "",
    help: "Integration grid spacing, metres (instead of --points)",
};

/// Kernel window function.
pub static KERNEL: OptionName = OptionName {
    library: "BasisOptions::kernel",
    flag: Some("--kernel"),
    scene: Some("basis.kernel"),
    python: Some("kernel"),
    c: Some("kernel"),
    value_prefix: "",
    help: "Kernel window function",
};

/// Support radius factor F.
pub static SUPPORT_FACTOR: OptionName = OptionName {
    library: "BasisOptions::support.factor",
    flag: Some("--support"),
    scene: Some("basis.support"),
    python: Some("support_factor"),
    c: Some("support_factor"),
    value_prefix: "",
    help: "Support radius = F x distance to the n-th nearest other centre",
};

/// The n of the support rule.
pub static SUPPORT_NEIGHBOR: OptionName = OptionName {
    library: "BasisOptions::support.neighbor",
    flag: Some("--support-neighbor"),
    scene: Some("basis.support_neighbor"),
    python: Some("support_neighbor"),
    c: Some("support_neighbor"),
    value_prefix: "",
    help: "The n in --support",
};

/// Relative eigen-residual tolerance.
pub static TOL: OptionName = OptionName {
    library: "BasisOptions::tol",
    flag: Some("--tol"),
    scene: Some("basis.eigen_tol"),
    python: Some("tol"),
    c: Some("tol"),
    value_prefix: "",
    help: "Relative residual tolerance of the eigensolver(s)",
};

/// Eigensolver iteration cap (scenes use the default).
pub static MAX_ITER: OptionName = OptionName {
    library: "BasisOptions::max_iter",
    flag: Some("--max-iter"),
    scene: None,
    python: Some("max_iter"),
    c: Some("max_iter"),
    value_prefix: "",
    help: "Eigensolver iteration cap",
};

/// How H_w and M are stored: both triangles, the upper triangle only, or auto.
pub static MATRIX_STORAGE: OptionName = OptionName {
    library: "BasisOptions::matrix_storage",
    flag: Some("--matrix-storage"),
    scene: None,
    python: Some("matrix_storage"),
    c: None,
    value_prefix: "",
    help: "How H_w and M are stored: upper (the upper triangle alone: half their memory, \
           the same basis; native LOBPCG only, no boundary regions), full (both triangles) or \
           auto (upper where the solver takes it, else full)",
};

/// Young's modulus E, Pa.
pub static YOUNGS: OptionName = OptionName {
    library: "Material::youngs",
    flag: Some("--youngs"),
    scene: Some("material.youngs"),
    python: Some("youngs"),
    c: None,
    value_prefix: "",
    help: "Young's modulus E, Pa",
};

/// Poisson ratio nu.
pub static POISSON: OptionName = OptionName {
    library: "Material::poisson",
    flag: Some("--poisson"),
    scene: Some("material.poisson"),
    python: Some("poisson"),
    c: None,
    value_prefix: "",
    help: "Poisson ratio nu, in (-1, 0.5)",
};

/// Density rho, kg/m^3.
pub static DENSITY: OptionName = OptionName {
    library: "Material::density",
    flag: Some("--density"),
    scene: Some("material.density"),
    python: Some("density"),
    c: None,
    value_prefix: "",
    help: "Density rho, kg/m^3",
};

/// A point cloud's total volume, m^3.
pub static VOLUME: OptionName = OptionName {
    library: "CloudVolumeOptions::total_volume",
    flag: Some("--volume"),
    scene: Some("basis.volume"),
    python: Some("total_volume"),
    c: None,
    value_prefix: "",
    help: "Point clouds: total object volume, m^3 (default: voxel-occupancy estimate)",
};

/// A point cloud's voxel edge for the volume estimate, metres.
pub static VOXEL: OptionName = OptionName {
    library: "CloudVolumeOptions::voxel",
    flag: Some("--voxel"),
    scene: Some("basis.voxel"),
    python: Some("voxel"),
    c: None,
    value_prefix: "",
    help: "Point clouds: voxel edge for the volume estimate, metres (default: 2 x median \
           spacing)",
};

/// Kernel spacing factor near boundary regions.
pub static DENSITY_BOUNDARIES: OptionName = OptionName {
    library: "DensityBands::boundaries",
    flag: Some("--density-boundaries"),
    scene: Some("basis.density_boundaries"),
    python: Some("density_boundaries"),
    c: None,
    value_prefix: "",
    help: "Kernel spacing factor within the band around each boundary region's surface (the \
           held and driven parts of an aware basis): 2 halves the spacing there, 1 is uniform \
           placement; K stays the same, the kernels move [1/8, 8]",
};

/// Kernel spacing factor at material interfaces.
pub static DENSITY_INTERFACES: OptionName = OptionName {
    library: "DensityBands::interfaces",
    flag: Some("--density-interfaces"),
    scene: Some("basis.density_interfaces"),
    python: Some("density_interfaces"),
    c: None,
    value_prefix: "",
    help: "Kernel spacing factor within the band around material interfaces (modulus or \
           density changing by more than 1.5x between neighbouring points: overrides, label \
           and modulus images); 1 is uniform placement [1/8, 8]",
};

/// Half-width of the refined bands, in kernel spacings.
pub static DENSITY_BAND: OptionName = OptionName {
    library: "DensityBands::band",
    flag: Some("--density-band"),
    scene: Some("basis.density_band"),
    python: Some("density_band"),
    c: None,
    value_prefix: "",
    help: "Half-width of the refined bands in kernel spacings h0 = (V / K)^(1/3); the factor \
           grades back to 1 over one more band width",
};

/// Largest kernel spacing factor on thin parts.
pub static DENSITY_THIN: OptionName = OptionName {
    library: "DensityBands::thin",
    flag: Some("--density-thin"),
    scene: Some("basis.density_thin"),
    python: Some("density_thin"),
    c: None,
    value_prefix: "",
    help: "Largest kernel spacing factor on parts thinner than 3 kernel spacings (local \
           thickness from the integration points' depth below the surface), so that about 3 \
           kernels lie across them; 1 is uniform placement [1/8, 8]; one process only",
};

/// User regions with their own kernel spacing factor.
pub static DENSITY_REGIONS: OptionName = OptionName {
    library: "KernelDensity::regions",
    flag: Some("--density-region"),
    scene: None,
    python: Some("density_regions"),
    c: None,
    value_prefix: "",
    help: "A region with its own kernel spacing factor, REGION@FACTOR (box:X0,Y0,Z0,X1,Y1,Z1, \
           sphere:CX,CY,CZ,R or halfspace:PX,PY,PZ,NX,NY,NZ, metres; factor in [1/8, 8], 2 = \
           twice as fine); repeat for several, the last one holding a point wins",
};

/// Accept a mesh with holes.
pub static ALLOW_OPEN_MESH: OptionName = OptionName {
    library: "ShapeOptions::allow_open_mesh",
    flag: Some("--allow-open-mesh"),
    scene: Some("allow_open_mesh"),
    python: Some("allow_open_mesh"),
    c: None,
    value_prefix: "",
    help: "Accept a mesh with holes (inside = winding number >= 0.5)",
};

/// The boundary regions a boundary-aware basis follows (scenes take them from the
/// boundaries).
pub static REGIONS: OptionName = OptionName {
    library: "BasisOptions::boundary_regions",
    flag: Some("--region"),
    scene: None,
    python: Some("regions"),
    c: None,
    value_prefix: "",
    help: "A boundary region the basis follows exactly (a boundary-aware basis: one lift per \
           region, free modes that vanish there; docs/math.md), rest coordinates in metres: \
           box:X0,Y0,Z0,X1,Y1,Z1, sphere:CX,CY,CZ,R or halfspace:PX,PY,PZ,NX,NY,NZ. Repeat for \
           several regions (at most --modes)",
};

/// How a scene's basis treats its boundary regions (`aware` or `free`).
pub static BOUNDARIES: OptionName = OptionName {
    library: "BoundaryModes",
    flag: Some("--boundaries"),
    scene: Some("basis.boundaries"),
    python: None,
    c: None,
    value_prefix: "",
    help: "Boundary-aware basis (aware) or global modes (free)",
};

/// The eigensolver.
pub static SOLVER: OptionName = OptionName {
    library: "BasisOptions::solver",
    flag: Some("--solver"),
    scene: Some("basis.eigensolver"),
    python: Some("eigensolver"),
    c: Some("solver"),
    value_prefix: "",
    help: "Eigensolver",
};

/// A SLEPc configuration (a preset of PETSc options).
pub static SLEPC: OptionName = OptionName {
    library: "BasisOptions::solver",
    flag: Some("--slepc"),
    scene: Some("basis.eigensolver"),
    python: Some("eigensolver"),
    c: None,
    value_prefix: "slepc:",
    help: "SLEPc configuration: lobpcg-gamg (default), ks-sinvert, lobpcg-hypre",
};

/// The native LOBPCG's settings, by their scene-file names.
pub static LOBPCG: OptionName = OptionName {
    library: "BasisOptions::solver",
    flag: Some("--lobpcg"),
    scene: Some("basis.eigensolver"),
    python: Some("eigensolver"),
    c: None,
    value_prefix: "lobpcg:",
    help: "LOBPCG settings for --solver lobpcg, KEY=VALUE pairs separated by commas, e.g. \
           guard=16,shift_factor=1e-3,preconditioner=incomplete_cholesky (keys: guard, \
           preconditioner, shift_factor, max_factor_entries, max_fill_ratio, escalate_after, \
           recompute_every, restart_tol, ortho_drop, svqb_drop, seed; the others keep their \
           defaults, docs/guide.md)",
};

/// PETSc options on top of a SLEPc configuration.
pub static PETSC_OPTIONS: OptionName = OptionName {
    library: "BasisOptions::solver",
    flag: Some("--petsc-options"),
    scene: Some("basis.eigensolver"),
    python: Some("eigensolver"),
    c: None,
    value_prefix: "slepc:CONFIG:",
    help: "PETSc options for --solver slepc, e.g. \"-eps_type jd -st_pc_type gamg\" (applied \
           after the --slepc preset; values starting with '-' are fine inside the quotes)",
};

/// Every row, for the checks that hold each front end to the table.
pub static ALL: [&OptionName; 27] = [
    &KERNELS,
    &MODES,
    &POINTS,
    &SPACING,
    &KERNEL,
    &SUPPORT_FACTOR,
    &SUPPORT_NEIGHBOR,
    &TOL,
    &MAX_ITER,
    &MATRIX_STORAGE,
    &YOUNGS,
    &POISSON,
    &DENSITY,
    &VOLUME,
    &VOXEL,
    &ALLOW_OPEN_MESH,
    &REGIONS,
    &DENSITY_BOUNDARIES,
    &DENSITY_INTERFACES,
    &DENSITY_BAND,
    &DENSITY_THIN,
    &DENSITY_REGIONS,
    &BOUNDARIES,
    &SOLVER,
    &SLEPC,
    &LOBPCG,
    &PETSC_OPTIONS,
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_front_names_each_option_once() {
        for front in [
            Front::Library,
            Front::Flags,
            Front::Scene,
            Front::Python,
            Front::C,
        ] {
            let mut seen = std::collections::BTreeMap::new();
            for o in ALL {
                // The eigensolver's string carries the solver, a SLEPc configuration and its
                // PETSc options in every front end but the command line's.
                let shared = o.value_prefix.is_empty() && !std::ptr::eq(o, &SOLVER);
                if let (Some(name), true) = (o.own_name(front), shared) {
                    if let Some(other) = seen.insert(name, o.library) {
                        panic!("{front:?}: {name} names both {other} and {}", o.library);
                    }
                }
            }
        }
    }

    #[test]
    fn names_and_settings_follow_the_front() {
        let advice = || format!("raise {} or use {}", TOL, SOLVER.with("lobpcg"));
        assert_eq!(
            advice(),
            "raise BasisOptions::tol or use BasisOptions::solver = \"lobpcg\""
        );
        assert_eq!(
            Front::Flags.scope(advice),
            "raise --tol or use --solver lobpcg"
        );
        assert_eq!(
            Front::Scene.scope(advice),
            "raise basis.eigen_tol or use basis.eigensolver = \"lobpcg\""
        );
        assert_eq!(
            Front::Python.scope(advice),
            "raise tol or use eigensolver=\"lobpcg\""
        );
        let slepc = || {
            format!(
                "{} or {}",
                SLEPC.with("ks-sinvert"),
                PETSC_OPTIONS.with("-a 1")
            )
        };
        assert_eq!(
            Front::Flags.scope(slepc),
            "--slepc ks-sinvert or --petsc-options \"-a 1\""
        );
        assert_eq!(
            Front::Scene.scope(slepc),
            "basis.eigensolver = \"slepc:ks-sinvert\" or basis.eigensolver = \
             \"slepc:CONFIG:-a 1\""
        );
        // No scene key: the library's name.
        assert_eq!(Front::Scene.render(&MAX_ITER), "BasisOptions::max_iter");
    }
}
