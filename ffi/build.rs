//! Generates the PETSc/SLEPc bindings when the `petsc` feature is on; does nothing otherwise.

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=wrapper.h");
    #[cfg(feature = "petsc")]
    petsc::generate();
}

#[cfg(feature = "petsc")]
mod petsc {
    use std::path::PathBuf;

    const INSTALL_HINT: &str = "freeform's `slepc` feature needs PETSc/SLEPc 3.18 and OpenMPI \
        development files. On Debian/Ubuntu: apt-get install -y --no-install-recommends \
        libslepc-real-dev pkg-config libclang-dev libopenblas0 (see docs/slepc.md)";

    /// Functions the safe layer calls (bindgen pulls in the types they need).
    const FUNCTIONS: &[&str] = &[
        "Slepc(Initialize|Finalize|Initialized)",
        "Petsc(Initialized|Finalized|PushErrorHandler|PopErrorHandler|PopSignalHandler)",
        "PetscOptions(InsertString|ClearValue|SetValue|HasName)",
        "PetscViewer(BinaryOpen|Destroy)",
        "MatShell(SetOperation|GetContext|SetContextDestroy)",
        "PCShell(SetApply|SetContext|GetContext|SetDestroy|SetName)",
        "Mat(CreateShell|Create|CreateVecs|SetSizes|SetType|SeqAIJSetPreallocation|MPIAIJSetPreallocation|SeqAIJSetPreallocationCSR|MPIAIJSetPreallocationCSR|SetValues|AssemblyBegin|AssemblyEnd|Destroy|GetOwnershipRange|GetSize|SetOption|View|Load|Mult|Norm|SetFromOptions|AXPY)",
        "Vec(Create|CreateMPI|SetSizes|SetFromOptions|Destroy|GetArrayRead|RestoreArrayRead|GetArray|RestoreArray|GetOwnershipRange|GetSize|GetLocalSize|Duplicate|Set|AssemblyBegin|AssemblyEnd)",
        "VecScatter(CreateToAll|Begin|End|Destroy)",
        "EPS(Create|SetOperators|SetProblemType|SetDimensions|SetTolerances|SetWhichEigenpairs|SetTarget|SetType|GetType|GetST|SetFromOptions|Solve|GetConverged|GetEigenpair|GetIterationNumber|GetConvergedReason|Destroy|SetConvergenceTest|GetDimensions|GetTolerances)",
        "EPSLOBPCG(GetBlockSize|SetBlockSize)",
        "ST(SetType|GetType|GetKSP|SetShift|GetShift)",
        "KSP(Create|Destroy|SetOperators|SetTolerances|SetFromOptions|Solve|GetIterationNumber|GetConvergedReason|SetType|GetType|GetPC)",
        "PC(SetType|GetType|FactorSetMatSolverType|FactorGetMatSolverType)",
        "MPI_(Comm_rank|Comm_size|Allreduce|Allgather|Allgatherv|Gather|Gatherv|Bcast|Barrier|Abort|Initialized|Finalized)",
    ];

    pub fn generate() {
        let slepc = pkg_config::Config::new()
            .atleast_version("3.18")
            .probe("slepc")
            .unwrap_or_else(|e| panic!("pkg-config could not find `slepc` ({e}). {INSTALL_HINT}"));
        // PETSc's .pc lacks the MPI include directory: take it from OpenMPI's module.
        let mpi = pkg_config::probe_library("ompi-c")
            .unwrap_or_else(|e| panic!("pkg-config could not find `ompi-c` ({e}). {INSTALL_HINT}"));
        let mut builder = bindgen::Builder::default()
            .header("wrapper.h")
            .parse_callbacks(Box::new(bindgen::CargoCallbacks::new()))
            .default_enum_style(bindgen::EnumVariation::Consts)
            .prepend_enum_name(false)
            .layout_tests(false)
            .generate_comments(false)
            // Type-name constants: MATAIJ, EPSKRYLOVSCHUR, MATSOLVERMUMPS, ...
            .allowlist_var("(MAT|EPS|ST|KSP|PC|MATSOLVER)[A-Z0-9_]+")
            // MPI_COMM_WORLD etc. are macros over these statics (bindgen drops the macros).
            .allowlist_var(
                "ompi_mpi_(comm_world|comm_self|double|int|long_long_int|op_sum|op_max|op_min)",
            )
            .allowlist_var("PETSC_COMM_WORLD")
            .allowlist_var("PETSC_ERR_USER")
            .allowlist_type("PetscErrorType");
        for f in FUNCTIONS {
            builder = builder.allowlist_function(f);
        }
        for path in slepc.include_paths.iter().chain(&mpi.include_paths) {
            builder = builder.clang_arg(format!("-I{}", path.display()));
        }
        let bindings = builder.generate().unwrap_or_else(|e| {
            panic!("bindgen failed on the PETSc/SLEPc headers: {e}. {INSTALL_HINT}")
        });
        let out = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
        bindings
            .write_to_file(out.join("bindings.rs"))
            .expect("write bindings.rs into OUT_DIR");
    }
}
