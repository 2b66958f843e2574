//! The safe layer over [`crate::sys`]: [`Session`], [`Mat`], [`Vector`], [`Eps`], [`Ksp`].

use crate::sys;
use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::marker::PhantomData;
use std::path::Path;
use std::sync::{Mutex, MutexGuard};

/// A failed PETSc/SLEPc/MPI call.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("PETSc error {code} in {call}: {message}")]
pub struct PetscError {
    /// PETSc's error code (`PetscErrorCode`), or the MPI error code for `MPI_*` calls.
    pub code: i32,
    /// The PETSc/SLEPc function we called.
    pub call: &'static str,
    /// PETSc's message (what it would have printed), with the function chain it came through.
    pub message: String,
}

/// Result alias of the safe layer.
pub type Result<T, E = PetscError> = std::result::Result<T, E>;

/// The last error PETSc reported through [`record_error`]; taken by [`check`].
static LAST_ERROR: Mutex<String> = Mutex::new(String::new());

fn lock_last_error() -> MutexGuard<'static, String> {
    LAST_ERROR.lock().unwrap_or_else(|e| e.into_inner())
}

/// PETSc error handler that records the message instead of printing it.
///
/// PETSc calls it first with `PETSC_ERROR_INITIAL` where the error arose, then with
/// `PETSC_ERROR_REPEAT` in every caller on the way out; we keep the first message and the
/// chain of function names. Never panics (it runs inside C frames).
unsafe extern "C" fn record_error(
    _comm: sys::MPI_Comm,
    line: c_int,
    fun: *const c_char,
    file: *const c_char,
    n: sys::PetscErrorCode,
    p: sys::PetscErrorType,
    mess: *const c_char,
    _ctx: *mut c_void,
) -> sys::PetscErrorCode {
    let text = |ptr: *const c_char| {
        if ptr.is_null() {
            String::new()
        } else {
            // SAFETY: PETSc passes NUL-terminated strings (or NULL, handled above).
            unsafe { CStr::from_ptr(ptr) }
                .to_string_lossy()
                .trim()
                .to_string()
        }
    };
    let mut last = lock_last_error();
    if p == sys::PETSC_ERROR_INITIAL {
        *last = format!("{} [{}() at {}:{line}]", text(mess), text(fun), text(file));
    } else {
        last.push_str(&format!(" <- {}()", text(fun)));
    }
    n
}

/// Turn a PETSc error code into a `Result`, attaching PETSc's recorded message.
pub fn check(call: &'static str, code: sys::PetscErrorCode) -> Result<()> {
    if code == 0 {
        return Ok(());
    }
    let mut message = std::mem::take(&mut *lock_last_error());
    if message.is_empty() {
        message = format!("error code {code} (no message recorded)");
    }
    Err(PetscError {
        code,
        call,
        message,
    })
}

/// `n` as an MPI count (`int`), or an error naming the call.
fn mpi_count(call: &'static str, n: usize) -> Result<c_int> {
    c_int::try_from(n).map_err(|_| PetscError {
        call,
        code: -1,
        message: format!("{n} values do not fit one MPI count"),
    })
}

fn mpi_check(call: &'static str, code: c_int) -> Result<()> {
    if code == 0 {
        Ok(())
    } else {
        Err(PetscError {
            code,
            call,
            message: format!("MPI error code {code}"),
        })
    }
}

pub(crate) fn cstring(call: &'static str, s: &str) -> Result<CString> {
    CString::new(s).map_err(|_| PetscError {
        code: -1,
        call,
        message: format!("string {s:?} contains a NUL byte"),
    })
}

/// Convert an index or size to PETSc's (32-bit in Debian's build) `PetscInt`.
pub fn petsc_int(call: &'static str, v: usize) -> Result<sys::PetscInt> {
    sys::PetscInt::try_from(v).map_err(|_| PetscError {
        code: -1,
        call,
        message: format!(
            "{v} does not fit PETSc's {}-bit PetscInt",
            sys::PetscInt::BITS
        ),
    })
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum State {
    Uninitialized,
    /// Initialized; `at_exit` says whether an exit hook will finalize.
    Active,
    Finalized,
}

/// Process-wide PETSc state; its lock serializes every use of PETSc.
static STATE: Mutex<State> = Mutex::new(State::Uninitialized);

fn lock_state() -> MutexGuard<'static, State> {
    STATE.lock().unwrap_or_else(|e| e.into_inner())
}

extern "C" {
    fn atexit(callback: extern "C" fn()) -> c_int;
}

extern "C" fn finalize_at_exit() {
    // Errors cannot be reported at exit; PETSc has printed nothing (our handler records).
    let _ = finalize();
}

fn init_locked(state: &mut State, options: &[&str]) -> Result<()> {
    match *state {
        State::Active => return Ok(()),
        State::Finalized => {
            return Err(PetscError {
                code: -1,
                call: "SlepcInitialize",
                message: "PETSc was already finalized in this process; MPI cannot restart".into(),
            })
        }
        State::Uninitialized => {}
    }
    // argv must outlive PETSc: leak it (once per process).
    let mut args = vec!["freeform".to_string(), "-no_signal_handler".to_string()];
    args.extend(options.iter().map(|s| s.to_string()));
    let mut ptrs: Vec<*mut c_char> = Vec::with_capacity(args.len() + 1);
    for a in &args {
        ptrs.push(cstring("SlepcInitialize", a)?.into_raw());
    }
    ptrs.push(std::ptr::null_mut());
    let argv: &'static mut [*mut c_char] = Box::leak(ptrs.into_boxed_slice());
    let argc: &'static mut c_int = Box::leak(Box::new(args.len() as c_int));
    let argv_ptr: &'static mut *mut *mut c_char = Box::leak(Box::new(argv.as_mut_ptr()));
    // SAFETY: argc/argv are valid, NUL-terminated and leaked (outlive PETSc); no file, no help.
    let code = unsafe { sys::SlepcInitialize(argc, argv_ptr, std::ptr::null(), std::ptr::null()) };
    check("SlepcInitialize", code)?;
    // SAFETY: PETSc is initialized; the handler has the required signature and never unwinds.
    check("PetscPushErrorHandler", unsafe {
        sys::PetscPushErrorHandler(Some(record_error), std::ptr::null_mut())
    })?;
    *state = State::Active;
    Ok(())
}

/// Initialize PETSc/SLEPc (and MPI, unless already initialized) with command-line style
/// options such as `["-log_view"]` (`-no_signal_handler` is always added: PETSc's handlers
/// turn SIGPIPE into an MPI abort). A no-op if already initialized. The caller must call
/// [`finalize`] before exiting (under `mpirun`, a process that exits without it is reported
/// as aborted).
///
/// # Errors
/// PETSc's error, or an error if PETSc was already finalized in this process.
pub fn initialize(options: &[&str]) -> Result<()> {
    init_locked(&mut lock_state(), options)
}

/// Finalize SLEPc/PETSc (and MPI if PETSc started it). A no-op if never initialized or
/// already finalized. Waits for any open [`Session`] to close.
///
/// # Errors
/// PETSc's error from `SlepcFinalize`.
pub fn finalize() -> Result<()> {
    let mut state = lock_state();
    if *state != State::Active {
        return Ok(());
    }
    *state = State::Finalized;
    // SAFETY: PETSc is initialized and no session holds objects (we own the state lock).
    check("SlepcFinalize", unsafe { sys::SlepcFinalize() })
}

/// Exclusive access to PETSc for the current thread. PETSc objects made through a session
/// cannot outlive it.
pub struct Session {
    _guard: MutexGuard<'static, State>,
}

/// Open a session, initializing PETSc with no options first if needed (then PETSc is
/// finalized by an exit hook).
///
/// # Errors
/// PETSc's initialization error, or an error after [`finalize`].
pub fn session() -> Result<Session> {
    let mut state = lock_state();
    if *state == State::Uninitialized {
        init_locked(&mut state, &[])?;
        // SAFETY: registering a plain extern "C" function with the C library.
        unsafe { atexit(finalize_at_exit) };
    } else if *state == State::Finalized {
        init_locked(&mut state, &[])?; // reports the "already finalized" error
    }
    Ok(Session { _guard: state })
}

/// An MPI communicator (a raw `MPI_Comm`; the predefined ones need no freeing).
#[derive(Debug, Clone, Copy)]
pub struct Comm(sys::MPI_Comm);

impl Comm {
    /// The raw communicator, for the crate's own calls.
    pub(crate) fn raw(self) -> sys::MPI_Comm {
        self.0
    }
}

impl Session {
    /// `PETSC_COMM_WORLD` (all ranks of the run; `MPI_COMM_WORLD` unless changed before
    /// initialization).
    pub fn world(&self) -> Comm {
        // SAFETY: PETSc is initialized while a session exists; the global is then set.
        Comm(unsafe { sys::PETSC_COMM_WORLD })
    }

    /// `MPI_COMM_SELF`: this rank alone.
    pub fn self_comm(&self) -> Comm {
        // SAFETY: taking the address of OpenMPI's predefined communicator (what the
        // MPI_COMM_SELF macro expands to); bindgen drops that macro.
        Comm(std::ptr::addr_of_mut!(sys::ompi_mpi_comm_self).cast())
    }

    /// This process's rank in `comm`.
    pub fn rank(&self, comm: Comm) -> Result<usize> {
        let mut r: c_int = 0;
        // SAFETY: valid communicator, MPI initialized.
        mpi_check("MPI_Comm_rank", unsafe {
            sys::MPI_Comm_rank(comm.0, &mut r)
        })?;
        Ok(r as usize)
    }

    /// Number of ranks in `comm`.
    pub fn size(&self, comm: Comm) -> Result<usize> {
        let mut s: c_int = 0;
        // SAFETY: valid communicator, MPI initialized.
        mpi_check("MPI_Comm_size", unsafe {
            sys::MPI_Comm_size(comm.0, &mut s)
        })?;
        Ok(s as usize)
    }

    fn allreduce(&self, comm: Comm, values: &mut [f64], op: sys::MPI_Op) -> Result<()> {
        let send = values.to_vec();
        // SAFETY: buffers of equal length `values.len()` doubles; collective on comm.
        let code = unsafe {
            sys::MPI_Allreduce(
                send.as_ptr().cast(),
                values.as_mut_ptr().cast(),
                c_int::try_from(values.len()).unwrap_or(c_int::MAX),
                std::ptr::addr_of_mut!(sys::ompi_mpi_double).cast(),
                op,
                comm.0,
            )
        };
        mpi_check("MPI_Allreduce", code)
    }

    /// Element-wise sum of `values` over all ranks of `comm`, in place (collective).
    pub fn allreduce_sum(&self, comm: Comm, values: &mut [f64]) -> Result<()> {
        // SAFETY: address of OpenMPI's predefined MPI_SUM.
        let op = std::ptr::addr_of_mut!(sys::ompi_mpi_op_sum).cast();
        self.allreduce(comm, values, op)
    }

    /// Element-wise maximum of `values` over all ranks of `comm`, in place (collective).
    pub fn allreduce_max(&self, comm: Comm, values: &mut [f64]) -> Result<()> {
        // SAFETY: address of OpenMPI's predefined MPI_MAX.
        let op = std::ptr::addr_of_mut!(sys::ompi_mpi_op_max).cast();
        self.allreduce(comm, values, op)
    }

    /// Overwrite `values` on every rank of `comm` with rank `root`'s (collective; every rank
    /// passes the same length).
    pub fn broadcast(&self, comm: Comm, values: &mut [f64], root: usize) -> Result<()> {
        let count = c_int::try_from(values.len()).map_err(|_| PetscError {
            call: "MPI_Bcast",
            code: -1,
            message: format!("{} values do not fit one MPI count", values.len()),
        })?;
        let root = c_int::try_from(root).unwrap_or(c_int::MAX);
        // SAFETY: a buffer of `count` doubles on every rank; collective on comm.
        let code = unsafe {
            sys::MPI_Bcast(
                values.as_mut_ptr().cast(),
                count,
                std::ptr::addr_of_mut!(sys::ompi_mpi_double).cast(),
                root,
                comm.0,
            )
        };
        mpi_check("MPI_Bcast", code)
    }

    /// Every rank's `mine` (the same length on every rank), concatenated in rank order on
    /// every rank (collective, `MPI_Allgather`).
    pub fn all_gather(&self, comm: Comm, mine: &[f64]) -> Result<Vec<f64>> {
        let size = self.size(comm)?;
        let count = mpi_count("MPI_Allgather", mine.len())?;
        let mut all = vec![0.0; mine.len() * size];
        // SAFETY: `count` doubles sent, `count` received from each of `size` ranks into a
        // buffer of size x count; collective on comm.
        let code = unsafe {
            let double = std::ptr::addr_of_mut!(sys::ompi_mpi_double).cast();
            sys::MPI_Allgather(
                mine.as_ptr().cast(),
                count,
                double,
                all.as_mut_ptr().cast(),
                count,
                double,
                comm.0,
            )
        };
        mpi_check("MPI_Allgather", code)?;
        Ok(all)
    }

    /// Every rank's `mine` (any lengths, each below 2^31) concatenated in rank order on rank
    /// `root`; `None` on the other ranks (collective, `MPI_Gatherv`).
    pub fn gather_to_root(
        &self,
        comm: Comm,
        mine: &[f64],
        root: usize,
    ) -> Result<Option<Vec<f64>>> {
        let (rank, size) = (self.rank(comm)?, self.size(comm)?);
        let counts: Vec<c_int> = self
            .all_gather(comm, &[mine.len() as f64])?
            .into_iter()
            .map(|c| mpi_count("MPI_Gatherv", c as usize))
            .collect::<Result<_>>()?;
        let mut displs = Vec::with_capacity(size);
        let mut total = 0usize;
        for &c in &counts {
            displs.push(mpi_count("MPI_Gatherv", total)?);
            total += c as usize;
        }
        let mut all = if rank == root {
            vec![0.0; total]
        } else {
            Vec::new()
        };
        let root_c = mpi_count("MPI_Gatherv", root)?;
        // SAFETY: `mine.len()` doubles sent; on root, a buffer of sum(counts) doubles with
        // displacements from the same counts; collective on comm.
        let code = unsafe {
            let double = std::ptr::addr_of_mut!(sys::ompi_mpi_double).cast();
            sys::MPI_Gatherv(
                mine.as_ptr().cast(),
                counts[rank],
                double,
                all.as_mut_ptr().cast(),
                counts.as_ptr(),
                displs.as_ptr(),
                double,
                root_c,
                comm.0,
            )
        };
        mpi_check("MPI_Gatherv", code)?;
        Ok((rank == root).then_some(all))
    }

    /// Insert options into PETSc's global database, e.g. `"-eps_type lobpcg -st_pc_type
    /// gamg"`. Values starting with `-` survive here (they do not on a shell command line).
    pub fn options_insert(&self, options: &str) -> Result<()> {
        let c = cstring("PetscOptionsInsertString", options)?;
        // SAFETY: NUL-terminated string, global database (NULL).
        check("PetscOptionsInsertString", unsafe {
            sys::PetscOptionsInsertString(std::ptr::null_mut(), c.as_ptr())
        })
    }

    /// Remove one option (`"-eps_type"`) from the global database.
    pub fn options_clear(&self, name: &str) -> Result<()> {
        let c = cstring("PetscOptionsClearValue", name)?;
        // SAFETY: NUL-terminated string, global database (NULL).
        check("PetscOptionsClearValue", unsafe {
            sys::PetscOptionsClearValue(std::ptr::null_mut(), c.as_ptr())
        })
    }
}

/// A PETSc matrix (`Mat`), destroyed on drop.
pub struct Mat<'s> {
    pub(crate) raw: sys::Mat,
    pub(crate) _session: PhantomData<&'s Session>,
}

impl Drop for Mat<'_> {
    fn drop(&mut self) {
        // SAFETY: we own the handle; errors cannot be reported from drop.
        unsafe { sys::MatDestroy(&mut self.raw) };
    }
}

impl<'s> Mat<'s> {
    /// A square AIJ matrix of global size `n` x `n` on `comm`, from this rank's rows
    /// `first_row .. first_row + row_ptr.len() - 1` in CSR form: row r's global column indices
    /// are `cols[row_ptr[r]..row_ptr[r + 1]]` with values `vals[..]` at the same positions.
    /// The local column block equals the local row block (the layout of the vectors), and the
    /// ranks' row blocks must tile 0..n in rank order. `symmetric` marks the matrix symmetric
    /// for the solvers. One call per matrix (`Mat*AIJSetPreallocationCSR`: PETSc preallocates
    /// and copies the rows itself); the 32-bit column indices are handed over as they are
    /// where `PetscInt` is 32 bits (Debian's PETSc), without a copy. Collective on `comm`.
    ///
    /// # Errors
    /// PETSc's error; arrays of inconsistent lengths; a column index `>= n` or beyond
    /// `PetscInt`.
    #[allow(clippy::too_many_arguments)]
    pub fn aij_from_rows(
        _session: &'s Session,
        comm: Comm,
        n: usize,
        first_row: usize,
        row_ptr: &[usize],
        cols: &[u32],
        vals: &[f64],
        symmetric: bool,
    ) -> Result<Self> {
        let call = "MatMPIAIJSetPreallocationCSR";
        let local = row_ptr.len().saturating_sub(1);
        if cols.len() != vals.len()
            || row_ptr.first().copied().unwrap_or(0) != 0
            || row_ptr.last().copied().unwrap_or(0) != cols.len()
        {
            return Err(PetscError {
                code: -1,
                call,
                message: "CSR arrays disagree in length".into(),
            });
        }
        let limit = n.min(sys::PetscInt::MAX as usize);
        if let Some(&bad) = cols.iter().find(|&&c| c as usize >= limit) {
            return Err(PetscError {
                code: -1,
                call,
                message: format!("column index {bad} >= matrix size {n} (or beyond PetscInt)"),
            });
        }
        let ptr: Vec<sys::PetscInt> = row_ptr
            .iter()
            .map(|&p| petsc_int(call, p))
            .collect::<Result<_>>()?;
        let converted: Vec<sys::PetscInt>;
        let j: &[sys::PetscInt] = if std::mem::size_of::<sys::PetscInt>() == 4 {
            // SAFETY: same size and alignment as u32, and every index is below
            // PetscInt::MAX (checked above), so each u32 reads as the same PetscInt.
            unsafe { std::slice::from_raw_parts(cols.as_ptr().cast(), cols.len()) }
        } else {
            converted = cols.iter().map(|&c| c as sys::PetscInt).collect();
            &converted
        };
        let mut raw: sys::Mat = std::ptr::null_mut();
        // SAFETY: out-pointer to a fresh handle on a valid communicator.
        check("MatCreate", unsafe { sys::MatCreate(comm.0, &mut raw) })?;
        let mat = Mat {
            raw,
            _session: PhantomData,
        };
        let (nl, ng) = (
            petsc_int("MatSetSizes", local)?,
            petsc_int("MatSetSizes", n)?,
        );
        // SAFETY: valid handle (below as well); sizes checked; arrays of local + 1 and nnz
        // entries, read by PETSc during the calls only.
        check("MatSetSizes", unsafe {
            sys::MatSetSizes(mat.raw, nl, nl, ng, ng)
        })?;
        let aij = cstring("MatSetType", "aij")?;
        check("MatSetType", unsafe {
            sys::MatSetType(mat.raw, aij.as_ptr())
        })?;
        // Both calls are made; PETSc ignores the one that does not match the actual type.
        check("MatSeqAIJSetPreallocationCSR", unsafe {
            sys::MatSeqAIJSetPreallocationCSR(mat.raw, ptr.as_ptr(), j.as_ptr(), vals.as_ptr())
        })?;
        check(call, unsafe {
            sys::MatMPIAIJSetPreallocationCSR(mat.raw, ptr.as_ptr(), j.as_ptr(), vals.as_ptr())
        })?;
        // PETSc lays rows out in rank order from the local sizes: they must be the caller's.
        let (start, _) = mat.ownership_range()?;
        if start != first_row {
            return Err(PetscError {
                code: -1,
                call,
                message: format!(
                    "this rank's rows start at {first_row}, but the ranks' row counts place \
                     them at {start}: the row blocks must tile 0..{n} in rank order"
                ),
            });
        }
        if symmetric {
            for opt in [sys::MAT_SYMMETRIC, sys::MAT_SYMMETRY_ETERNAL] {
                check("MatSetOption", unsafe {
                    sys::MatSetOption(mat.raw, opt, sys::PETSC_TRUE)
                })?;
            }
        }
        Ok(mat)
    }

    /// The 1-norm (largest absolute column sum). Collective.
    pub fn norm_one(&self) -> Result<f64> {
        let mut v = 0.0;
        // SAFETY: valid handle, out-pointer.
        check("MatNorm", unsafe {
            sys::MatNorm(self.raw, sys::NORM_1, &mut v)
        })?;
        Ok(v)
    }

    /// `self += alpha x` in place. `same_pattern`: both matrices have the same nonzero
    /// pattern (then no memory is allocated); otherwise PETSc merges the patterns into a new
    /// one. Collective.
    pub fn axpy(&mut self, alpha: f64, x: &Mat<'s>, same_pattern: bool) -> Result<()> {
        let structure = if same_pattern {
            sys::SAME_NONZERO_PATTERN
        } else {
            sys::DIFFERENT_NONZERO_PATTERN
        };
        // SAFETY: valid handles of the same session.
        check("MatAXPY", unsafe {
            sys::MatAXPY(self.raw, alpha, x.raw, structure)
        })
    }

    /// Read a matrix from a PETSc binary file (as written by `MatView` with a binary viewer).
    /// Collective on `comm`.
    ///
    /// # Errors
    /// PETSc's error (missing file, wrong format).
    pub fn load_binary(_session: &'s Session, comm: Comm, path: &Path) -> Result<Self> {
        let p = cstring("PetscViewerBinaryOpen", &path.to_string_lossy())?;
        let mut viewer: sys::PetscViewer = std::ptr::null_mut();
        // SAFETY: valid comm and path; out-pointer.
        check("PetscViewerBinaryOpen", unsafe {
            sys::PetscViewerBinaryOpen(comm.0, p.as_ptr(), sys::FILE_MODE_READ, &mut viewer)
        })?;
        let mut raw: sys::Mat = std::ptr::null_mut();
        let result = (|| {
            check("MatCreate", unsafe { sys::MatCreate(comm.0, &mut raw) })?;
            let aij = cstring("MatSetType", "aij")?;
            check("MatSetType", unsafe { sys::MatSetType(raw, aij.as_ptr()) })?;
            check("MatLoad", unsafe { sys::MatLoad(raw, viewer) })
        })();
        // SAFETY: we own the viewer.
        unsafe { sys::PetscViewerDestroy(&mut viewer) };
        let mat = Mat {
            raw,
            _session: PhantomData,
        };
        result.map(|_| mat)
    }

    /// Global size (rows, columns).
    pub fn size(&self) -> Result<(usize, usize)> {
        let (mut m, mut n) = (0, 0);
        // SAFETY: valid handle.
        check("MatGetSize", unsafe {
            sys::MatGetSize(self.raw, &mut m, &mut n)
        })?;
        Ok((m as usize, n as usize))
    }

    /// This rank's row range `[first, end)`.
    pub fn ownership_range(&self) -> Result<(usize, usize)> {
        let (mut a, mut b) = (0, 0);
        // SAFETY: valid handle.
        check("MatGetOwnershipRange", unsafe {
            sys::MatGetOwnershipRange(self.raw, &mut a, &mut b)
        })?;
        Ok((a as usize, b as usize))
    }

    /// A vector with this matrix's row layout, zero-initialized.
    pub fn create_vector(&self) -> Result<Vector<'s>> {
        let mut v: sys::Vec = std::ptr::null_mut();
        // SAFETY: valid handle; the left vector is not requested.
        check("MatCreateVecs", unsafe {
            sys::MatCreateVecs(self.raw, &mut v, std::ptr::null_mut())
        })?;
        let v = Vector {
            raw: v,
            _session: PhantomData,
        };
        check("VecSet", unsafe { sys::VecSet(v.raw, 0.0) })?;
        Ok(v)
    }

    /// y = A x.
    pub fn mult(&self, x: &Vector<'s>, y: &mut Vector<'s>) -> Result<()> {
        // SAFETY: valid handles with compatible layouts (PETSc checks and reports otherwise).
        check("MatMult", unsafe { sys::MatMult(self.raw, x.raw, y.raw) })
    }

    /// The raw handle (for calls the safe layer does not cover). Valid while `self` lives.
    pub fn as_raw(&self) -> sys::Mat {
        self.raw
    }
}

/// A PETSc vector (`Vec`), destroyed on drop.
pub struct Vector<'s> {
    raw: sys::Vec,
    _session: PhantomData<&'s Session>,
}

impl Drop for Vector<'_> {
    fn drop(&mut self) {
        // SAFETY: we own the handle.
        unsafe { sys::VecDestroy(&mut self.raw) };
    }
}

impl Vector<'_> {
    /// This rank's entries, copied out.
    pub fn local_values(&self) -> Result<Vec<f64>> {
        let mut n: sys::PetscInt = 0;
        // SAFETY: valid handle; the array is read then restored.
        check("VecGetLocalSize", unsafe {
            sys::VecGetLocalSize(self.raw, &mut n)
        })?;
        let mut ptr: *const f64 = std::ptr::null();
        check("VecGetArrayRead", unsafe {
            sys::VecGetArrayRead(self.raw, &mut ptr)
        })?;
        let out = if n == 0 || ptr.is_null() {
            Vec::new()
        } else {
            // SAFETY: PETSc gives `n` contiguous local values.
            unsafe { std::slice::from_raw_parts(ptr, n as usize) }.to_vec()
        };
        check("VecRestoreArrayRead", unsafe {
            sys::VecRestoreArrayRead(self.raw, &mut ptr)
        })?;
        Ok(out)
    }

    /// Overwrite this rank's entries with `values` (length = local size).
    pub fn set_local_values(&mut self, values: &[f64]) -> Result<()> {
        let mut n: sys::PetscInt = 0;
        // SAFETY: valid handle; the array is written then restored.
        check("VecGetLocalSize", unsafe {
            sys::VecGetLocalSize(self.raw, &mut n)
        })?;
        if n as usize != values.len() {
            return Err(PetscError {
                code: -1,
                call: "VecGetArray",
                message: format!("{} values for a local size of {n}", values.len()),
            });
        }
        let mut ptr: *mut f64 = std::ptr::null_mut();
        check("VecGetArray", unsafe {
            sys::VecGetArray(self.raw, &mut ptr)
        })?;
        if n > 0 && !ptr.is_null() {
            // SAFETY: PETSc gives `n` contiguous writable local values.
            unsafe { std::slice::from_raw_parts_mut(ptr, n as usize) }.copy_from_slice(values);
        }
        check("VecRestoreArray", unsafe {
            sys::VecRestoreArray(self.raw, &mut ptr)
        })
    }

    /// All entries (every rank's), gathered onto every rank in global order. Collective.
    pub fn gather_all(&self) -> Result<Vec<f64>> {
        let mut scatter: sys::VecScatter = std::ptr::null_mut();
        let mut all: sys::Vec = std::ptr::null_mut();
        // SAFETY: valid handle; scatter context and output vector are destroyed below.
        check("VecScatterCreateToAll", unsafe {
            sys::VecScatterCreateToAll(self.raw, &mut scatter, &mut all)
        })?;
        let all = Vector {
            raw: all,
            _session: PhantomData,
        };
        let result = (|| {
            check("VecScatterBegin", unsafe {
                sys::VecScatterBegin(
                    scatter,
                    self.raw,
                    all.raw,
                    sys::INSERT_VALUES,
                    sys::SCATTER_FORWARD,
                )
            })?;
            check("VecScatterEnd", unsafe {
                sys::VecScatterEnd(
                    scatter,
                    self.raw,
                    all.raw,
                    sys::INSERT_VALUES,
                    sys::SCATTER_FORWARD,
                )
            })?;
            all.local_values()
        })();
        unsafe { sys::VecScatterDestroy(&mut scatter) };
        result
    }
}

/// Problem types of [`Eps::set_problem_type`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ProblemType {
    /// Generalized Hermitian: A x = lambda B x, A symmetric, B SPD.
    Ghep,
}

/// Which eigenpairs [`Eps`] looks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Which {
    /// Smallest real part (LOBPCG).
    SmallestReal,
    /// Closest to the target (shift-and-invert).
    TargetMagnitude,
}

/// Convergence tests of [`Eps::set_convergence_test`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Convergence {
    /// ||r|| / ((||A|| + |lambda| ||B||) ||x||): freeform's own tolerance definition.
    Norm,
    /// ||r|| / |lambda| (SLEPc's default; breaks on a zero eigenvalue).
    Relative,
    /// ||r||.
    Absolute,
}

/// A SLEPc eigensolver context (`EPS`), destroyed on drop.
pub struct Eps<'s> {
    raw: sys::EPS,
    _session: PhantomData<&'s Session>,
}

impl Drop for Eps<'_> {
    fn drop(&mut self) {
        // SAFETY: we own the handle.
        unsafe { sys::EPSDestroy(&mut self.raw) };
    }
}

fn name_of(call: &'static str, ptr: *const c_char) -> Result<String> {
    if ptr.is_null() {
        return Err(PetscError {
            code: -1,
            call,
            message: "type not set".into(),
        });
    }
    // SAFETY: PETSc type names are NUL-terminated static strings.
    Ok(unsafe { CStr::from_ptr(ptr) }
        .to_string_lossy()
        .into_owned())
}

impl<'s> Eps<'s> {
    /// A new eigensolver on `comm`.
    pub fn new(_session: &'s Session, comm: Comm) -> Result<Self> {
        let mut raw: sys::EPS = std::ptr::null_mut();
        // SAFETY: out-pointer on a valid communicator.
        check("EPSCreate", unsafe { sys::EPSCreate(comm.0, &mut raw) })?;
        Ok(Eps {
            raw,
            _session: PhantomData,
        })
    }

    /// The pencil (A, B) of A x = lambda B x. Both must outlive the solve.
    pub fn set_operators(&mut self, a: &Mat<'s>, b: &Mat<'s>) -> Result<()> {
        // SAFETY: valid handles (EPS takes its own references).
        check("EPSSetOperators", unsafe {
            sys::EPSSetOperators(self.raw, a.raw, b.raw)
        })
    }

    /// Problem type.
    pub fn set_problem_type(&mut self, t: ProblemType) -> Result<()> {
        let t = match t {
            ProblemType::Ghep => sys::EPS_GHEP,
        };
        check("EPSSetProblemType", unsafe {
            sys::EPSSetProblemType(self.raw, t)
        })
    }

    /// Number of eigenpairs wanted (subspace sizes left to SLEPc).
    pub fn set_dimensions(&mut self, nev: usize) -> Result<()> {
        let nev = petsc_int("EPSSetDimensions", nev)?;
        check("EPSSetDimensions", unsafe {
            sys::EPSSetDimensions(self.raw, nev, -2, -2) // PETSC_DEFAULT
        })
    }

    /// Tolerance and iteration cap.
    pub fn set_tolerances(&mut self, tol: f64, max_iter: usize) -> Result<()> {
        let it = petsc_int("EPSSetTolerances", max_iter)?;
        check("EPSSetTolerances", unsafe {
            sys::EPSSetTolerances(self.raw, tol, it)
        })
    }

    /// Which part of the spectrum.
    pub fn set_which(&mut self, which: Which) -> Result<()> {
        let w = match which {
            Which::SmallestReal => sys::EPS_SMALLEST_REAL,
            Which::TargetMagnitude => sys::EPS_TARGET_MAGNITUDE,
        };
        check("EPSSetWhichEigenpairs", unsafe {
            sys::EPSSetWhichEigenpairs(self.raw, w)
        })
    }

    /// Target value for [`Which::TargetMagnitude`] (the shift of shift-and-invert).
    pub fn set_target(&mut self, target: f64) -> Result<()> {
        check("EPSSetTarget", unsafe {
            sys::EPSSetTarget(self.raw, target)
        })
    }

    /// Convergence test.
    pub fn set_convergence_test(&mut self, conv: Convergence) -> Result<()> {
        let c = match conv {
            Convergence::Norm => sys::EPS_CONV_NORM,
            Convergence::Relative => sys::EPS_CONV_REL,
            Convergence::Absolute => sys::EPS_CONV_ABS,
        };
        check("EPSSetConvergenceTest", unsafe {
            sys::EPSSetConvergenceTest(self.raw, c)
        })
    }

    /// Solver type by SLEPc name ("krylovschur", "lobpcg", ...).
    pub fn set_type(&mut self, name: &str) -> Result<()> {
        let c = cstring("EPSSetType", name)?;
        check("EPSSetType", unsafe {
            sys::EPSSetType(self.raw, c.as_ptr())
        })
    }

    /// Spectral transformation, its linear solver and preconditioner by PETSc names, e.g.
    /// ("sinvert", "preonly", "cholesky", Some("mumps")). `None` leaves a part at its default.
    pub fn set_spectral_transform(
        &mut self,
        st_type: Option<&str>,
        ksp_type: Option<&str>,
        pc_type: Option<&str>,
        factor_package: Option<&str>,
    ) -> Result<()> {
        let (st, _ksp, pc) = self.st_ksp_pc()?;
        // SAFETY (all calls below): sub-object handles owned by the EPS, valid while it lives.
        if let Some(t) = st_type {
            let c = cstring("STSetType", t)?;
            check("STSetType", unsafe { sys::STSetType(st, c.as_ptr()) })?;
        }
        if let Some(t) = ksp_type {
            let c = cstring("KSPSetType", t)?;
            check("KSPSetType", unsafe { sys::KSPSetType(_ksp, c.as_ptr()) })?;
        }
        if let Some(t) = pc_type {
            let c = cstring("PCSetType", t)?;
            check("PCSetType", unsafe { sys::PCSetType(pc, c.as_ptr()) })?;
        }
        if let Some(t) = factor_package {
            let c = cstring("PCFactorSetMatSolverType", t)?;
            check("PCFactorSetMatSolverType", unsafe {
                sys::PCFactorSetMatSolverType(pc, c.as_ptr())
            })?;
        }
        Ok(())
    }

    /// Shift of the spectral transformation (the preconditioner's A - sigma B for "precond").
    pub fn set_st_shift(&mut self, shift: f64) -> Result<()> {
        let (st, _, _) = self.st_ksp_pc()?;
        check("STSetShift", unsafe { sys::STSetShift(st, shift) })
    }

    pub(crate) fn st_ksp_pc(&self) -> Result<(sys::ST, sys::KSP, sys::PC)> {
        let mut st: sys::ST = std::ptr::null_mut();
        let mut ksp: sys::KSP = std::ptr::null_mut();
        let mut pc: sys::PC = std::ptr::null_mut();
        // SAFETY: out-pointers; the objects belong to the EPS.
        check("EPSGetST", unsafe { sys::EPSGetST(self.raw, &mut st) })?;
        check("STGetKSP", unsafe { sys::STGetKSP(st, &mut ksp) })?;
        check("KSPGetPC", unsafe { sys::KSPGetPC(ksp, &mut pc) })?;
        Ok((st, ksp, pc))
    }

    /// Apply the options database (`-eps_*`, `-st_*`, ...): always call before solving.
    pub fn set_from_options(&mut self) -> Result<()> {
        check("EPSSetFromOptions", unsafe {
            sys::EPSSetFromOptions(self.raw)
        })
    }

    /// Run the solver (collective).
    pub fn solve(&mut self) -> Result<()> {
        check("EPSSolve", unsafe { sys::EPSSolve(self.raw) })
    }

    /// Block size of SLEPc's LOBPCG (`EPSLOBPCGGetBlockSize`): the one set by
    /// `-eps_lobpcg_blocksize`, or after setup SLEPc's default min(16, nev). 0 before setup
    /// when none was set. An error if the solver type is not `lobpcg`.
    pub fn lobpcg_block_size(&self) -> Result<usize> {
        let mut bs: sys::PetscInt = 0;
        // SAFETY: valid handle, out-pointer; PETSc reports a non-LOBPCG type as an error.
        check("EPSLOBPCGGetBlockSize", unsafe {
            sys::EPSLOBPCGGetBlockSize(self.raw, &mut bs)
        })?;
        Ok(bs.max(0) as usize)
    }

    /// Set the LOBPCG block size (as `-eps_lobpcg_blocksize`; options applied later win).
    /// An error if the solver type is not `lobpcg`.
    pub fn set_lobpcg_block_size(&mut self, block: usize) -> Result<()> {
        let bs = petsc_int("EPSLOBPCGSetBlockSize", block)?;
        // SAFETY: valid handle; PETSc checks the value.
        check("EPSLOBPCGSetBlockSize", unsafe {
            sys::EPSLOBPCGSetBlockSize(self.raw, bs)
        })
    }

    /// Converged eigenpairs available.
    pub fn converged(&self) -> Result<usize> {
        let mut n: sys::PetscInt = 0;
        check("EPSGetConverged", unsafe {
            sys::EPSGetConverged(self.raw, &mut n)
        })?;
        Ok(n.max(0) as usize)
    }

    /// Iterations performed.
    pub fn iterations(&self) -> Result<usize> {
        let mut n: sys::PetscInt = 0;
        check("EPSGetIterationNumber", unsafe {
            sys::EPSGetIterationNumber(self.raw, &mut n)
        })?;
        Ok(n.max(0) as usize)
    }

    /// SLEPc's converged reason (> 0 converged, < 0 diverged, e.g. -1 iteration cap).
    pub fn converged_reason(&self) -> Result<i32> {
        let mut r: sys::EPSConvergedReason = 0;
        check("EPSGetConvergedReason", unsafe {
            sys::EPSGetConvergedReason(self.raw, &mut r)
        })?;
        Ok(r as i32)
    }

    /// Eigenpair `i` (0-based, i < [`Eps::converged`]): returns lambda and writes x into `x`
    /// (a vector from [`Mat::create_vector`] of A).
    pub fn eigenpair(&self, i: usize, x: &mut Vector<'s>) -> Result<f64> {
        let i = petsc_int("EPSGetEigenpair", i)?;
        let (mut kr, mut ki) = (0.0, 0.0);
        check("EPSGetEigenpair", unsafe {
            sys::EPSGetEigenpair(self.raw, i, &mut kr, &mut ki, x.raw, std::ptr::null_mut())
        })?;
        Ok(kr)
    }

    /// Names in use after setup: (EPS type, ST type, KSP type, PC type, factor package or "").
    pub fn describe(&self) -> Result<[String; 5]> {
        let (st, ksp, pc) = self.st_ksp_pc()?;
        let mut e: sys::EPSType = std::ptr::null();
        let mut s: sys::STType = std::ptr::null();
        let mut k: sys::KSPType = std::ptr::null();
        let mut p: sys::PCType = std::ptr::null();
        let mut f: sys::MatSolverType = std::ptr::null();
        check("EPSGetType", unsafe { sys::EPSGetType(self.raw, &mut e) })?;
        check("STGetType", unsafe { sys::STGetType(st, &mut s) })?;
        check("KSPGetType", unsafe { sys::KSPGetType(ksp, &mut k) })?;
        check("PCGetType", unsafe { sys::PCGetType(pc, &mut p) })?;
        // Fails for non-factor PCs; then there is no package to report.
        let package = if unsafe { sys::PCFactorGetMatSolverType(pc, &mut f) } == 0 && !f.is_null() {
            name_of("PCFactorGetMatSolverType", f)?
        } else {
            lock_last_error().clear();
            String::new()
        };
        Ok([
            name_of("EPSGetType", e)?,
            name_of("STGetType", s)?,
            name_of("KSPGetType", k)?,
            name_of("PCGetType", p).unwrap_or_default(),
            package,
        ])
    }
}

/// A PETSc linear solver (`KSP`), destroyed on drop.
pub struct Ksp<'s> {
    raw: sys::KSP,
    _session: PhantomData<&'s Session>,
}

impl Drop for Ksp<'_> {
    fn drop(&mut self) {
        // SAFETY: we own the handle.
        unsafe { sys::KSPDestroy(&mut self.raw) };
    }
}

impl<'s> Ksp<'s> {
    /// A new linear solver on `comm`.
    pub fn new(_session: &'s Session, comm: Comm) -> Result<Self> {
        let mut raw: sys::KSP = std::ptr::null_mut();
        // SAFETY: out-pointer on a valid communicator.
        check("KSPCreate", unsafe { sys::KSPCreate(comm.0, &mut raw) })?;
        Ok(Ksp {
            raw,
            _session: PhantomData,
        })
    }

    /// The system matrix (also used to build the preconditioner).
    pub fn set_operator(&mut self, a: &Mat<'s>) -> Result<()> {
        // SAFETY: valid handles (KSP takes its own references).
        check("KSPSetOperators", unsafe {
            sys::KSPSetOperators(self.raw, a.raw, a.raw)
        })
    }

    /// Solver and preconditioner by PETSc names ("cg", "gamg"); relative tolerance and
    /// iteration cap.
    pub fn configure(
        &mut self,
        ksp_type: &str,
        pc_type: &str,
        rtol: f64,
        max_iter: usize,
    ) -> Result<()> {
        let k = cstring("KSPSetType", ksp_type)?;
        let p = cstring("PCSetType", pc_type)?;
        let it = petsc_int("KSPSetTolerances", max_iter)?;
        let mut pc: sys::PC = std::ptr::null_mut();
        // SAFETY: valid handle; the PC belongs to the KSP. PETSC_DEFAULT (-2) for abstol/dtol.
        check("KSPSetType", unsafe {
            sys::KSPSetType(self.raw, k.as_ptr())
        })?;
        check("KSPGetPC", unsafe { sys::KSPGetPC(self.raw, &mut pc) })?;
        check("PCSetType", unsafe { sys::PCSetType(pc, p.as_ptr()) })?;
        check("KSPSetTolerances", unsafe {
            sys::KSPSetTolerances(self.raw, rtol, -2.0, -2.0, it)
        })
    }

    /// Apply the options database (`-ksp_*`, `-pc_*`).
    pub fn set_from_options(&mut self) -> Result<()> {
        check("KSPSetFromOptions", unsafe {
            sys::KSPSetFromOptions(self.raw)
        })
    }

    /// Solve A x = b; returns (iterations, PETSc's converged reason: > 0 converged).
    pub fn solve(&mut self, b: &Vector<'s>, x: &mut Vector<'s>) -> Result<(usize, i32)> {
        // SAFETY: valid handles with the operator's layout (PETSc checks).
        check("KSPSolve", unsafe { sys::KSPSolve(self.raw, b.raw, x.raw) })?;
        let mut its: sys::PetscInt = 0;
        let mut reason: sys::KSPConvergedReason = 0;
        check("KSPGetIterationNumber", unsafe {
            sys::KSPGetIterationNumber(self.raw, &mut its)
        })?;
        check("KSPGetConvergedReason", unsafe {
            sys::KSPGetConvergedReason(self.raw, &mut reason)
        })?;
        Ok((its.max(0) as usize, reason as i32))
    }
}

/// Abort every rank of `PETSC_COMM_WORLD` if there are several (after a panic on one rank,
/// so the others do not wait forever in a collective). A no-op on one rank, before
/// initialization, after finalization, or if another thread holds PETSc.
pub fn abort_world_if_parallel(code: i32) {
    // A panic while a session was open poisons the lock: still abort then.
    let state = match STATE.try_lock() {
        Ok(guard) => guard,
        Err(std::sync::TryLockError::Poisoned(p)) => p.into_inner(),
        Err(std::sync::TryLockError::WouldBlock) => return,
    };
    if *state != State::Active {
        return;
    }
    let mut size: c_int = 0;
    // SAFETY: PETSc (hence MPI) is initialized; we hold the state lock.
    unsafe {
        sys::MPI_Comm_size(sys::PETSC_COMM_WORLD, &mut size);
        if size > 1 {
            sys::MPI_Abort(sys::PETSC_COMM_WORLD, code);
        }
    }
}
