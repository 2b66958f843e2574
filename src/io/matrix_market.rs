//! Matrix exchange: MatrixMarket coordinate files (read and write) and PETSc's binary matrix
//! format (write), so another solver can be run on exactly our H_w and M.
//!
//! - [`write_matrix_market`]: `%%MatrixMarket matrix coordinate real symmetric`, the lower
//!   triangle, 1-based, values with 17 significant digits (exact round trip of every f64).
//! - [`read_matrix_market`]: coordinate `real`/`integer`/`pattern`, `general`/`symmetric`/
//!   `skew-symmetric`; duplicates are summed. Returns a [`SparseMatrix`] with both triangles.
//! - [`write_petsc_binary`]: PETSc's `MatView` binary layout (big-endian: class id 1211216,
//!   rows, columns, non-zeros, per-row counts, 0-based column indices as 32-bit ints, values
//!   as f64), which `MatLoad` reads on any number of ranks.
//! - [`write_matrices`] / [`read_matrices`]: the directory layout of `freeform export` and
//!   `freeform modes --from-matrices` (`hessian.mtx`, `mass.mtx`, `hessian.petsc`,
//!   `mass.petsc`).

use crate::sparse::{from_compressed, SparseMatrix, SparseMatrixRef};
use std::io::{BufRead, BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};

/// File name of H_w in an export directory.
pub const HESSIAN_MTX: &str = "hessian.mtx";
/// File name of M in an export directory.
pub const MASS_MTX: &str = "mass.mtx";
/// PETSc binary file of H_w in an export directory.
pub const HESSIAN_PETSC: &str = "hessian.petsc";
/// PETSc binary file of M in an export directory.
pub const MASS_PETSC: &str = "mass.petsc";

/// PETSc's class id that starts a binary matrix (`MAT_FILE_CLASSID`).
pub const PETSC_MAT_FILE_CLASSID: i32 = 1_211_216;

/// Matrix exchange failures.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MatrixFileError {
    /// Reading or writing the file failed.
    #[error("{path}: {source}")]
    Io {
        /// File involved.
        path: PathBuf,
        /// Underlying error.
        source: std::io::Error,
    },
    /// The file is not a MatrixMarket file we can read.
    #[error("{path}:{line}: {reason}")]
    Parse {
        /// File involved.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// The matrix does not fit the format (e.g. more than 2^31 - 1 entries for PETSc's
    /// 32-bit indices).
    #[error("{path}: {reason}")]
    TooLarge {
        /// File involved.
        path: PathBuf,
        /// What does not fit.
        reason: String,
    },
}

fn io_err(path: &Path) -> impl Fn(std::io::Error) -> MatrixFileError + '_ {
    move |source| MatrixFileError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Run `write` on a buffered temporary file next to `path`, then rename it to `path`: a
/// failed write never leaves a partial matrix under the final name.
fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<(), MatrixFileError> {
    let tmp = super::file::temp_path_for(path);
    let result = std::fs::File::create(&tmp)
        .and_then(|file| {
            let mut w = BufWriter::new(file);
            write(&mut w)?;
            w.flush()
        })
        .and_then(|()| std::fs::rename(&tmp, path));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result.map_err(io_err(path))
}

/// A read error on line `line`: invalid UTF-8 (a binary file) is a parse error, the rest I/O.
fn read_err(path: &Path, line: usize) -> impl Fn(std::io::Error) -> MatrixFileError + '_ {
    move |source| {
        if source.kind() == std::io::ErrorKind::InvalidData {
            MatrixFileError::Parse {
                path: path.to_path_buf(),
                line,
                reason: "not a text file (invalid UTF-8); expected a MatrixMarket file".into(),
            }
        } else {
            io_err(path)(source)
        }
    }
}

/// Write a symmetric matrix (both triangles stored, as [`SparseMatrix`] holds H_w and M) as a
/// MatrixMarket `coordinate real symmetric` file: the lower triangle, 1-based. `comment`
/// lines (without the `%`) go after the banner, e.g. units.
///
/// # Errors
/// [`MatrixFileError::Io`].
pub fn write_matrix_market(
    path: &Path,
    a: SparseMatrixRef<'_>,
    comment: &[&str],
) -> Result<(), MatrixFileError> {
    let sym = a.symbolic();
    let lower: usize = (0..a.ncols())
        .map(|j| {
            sym.row_idx()[sym.col_range(j)]
                .iter()
                .filter(|&&i| i as usize >= j)
                .count()
        })
        .sum();
    write_atomically(path, |w| {
        writeln!(w, "%%MatrixMarket matrix coordinate real symmetric")?;
        for c in comment {
            writeln!(w, "% {c}")?;
        }
        writeln!(w, "{} {} {lower}", a.nrows(), a.ncols())?;
        for j in 0..a.ncols() {
            let r = sym.col_range(j);
            for (&i, &v) in sym.row_idx()[r.clone()].iter().zip(&a.val()[r]) {
                if i as usize >= j {
                    writeln!(w, "{} {} {v:.16e}", i as usize + 1, j + 1)?;
                }
            }
        }
        Ok(())
    })
}

/// Write a dense matrix (e.g. eigenvectors, K x (m + 1)) as a MatrixMarket `array real
/// general` file (column-major, 17 significant digits).
///
/// # Errors
/// [`MatrixFileError::Io`].
pub fn write_dense_matrix_market(
    path: &Path,
    a: &faer::Mat<f64>,
    comment: &[&str],
) -> Result<(), MatrixFileError> {
    write_atomically(path, |w| {
        writeln!(w, "%%MatrixMarket matrix array real general")?;
        for c in comment {
            writeln!(w, "% {c}")?;
        }
        writeln!(w, "{} {}", a.nrows(), a.ncols())?;
        for j in 0..a.ncols() {
            for i in 0..a.nrows() {
                writeln!(w, "{:.16e}", a[(i, j)])?;
            }
        }
        Ok(())
    })
}

/// Read a MatrixMarket coordinate file into a square [`SparseMatrix`] (symmetric storage is
/// expanded to both triangles; duplicate entries are summed).
///
/// # Errors
/// [`MatrixFileError::Io`]; [`MatrixFileError::Parse`] for a bad banner, a binary file, an
/// `array` or `complex` file, a non-square size, an index out of range, a malformed or
/// non-finite value, a wrong entry count, or a size beyond the entries read (empty rows).
pub fn read_matrix_market(path: &Path) -> Result<SparseMatrix, MatrixFileError> {
    let file = std::fs::File::open(path).map_err(io_err(path))?;
    read_matrix_market_from(path, BufReader::new(file))
}

/// Parse MatrixMarket content from `reader` as [`read_matrix_market`] parses a file; `path`
/// only labels the errors. Memory stays proportional to the entries actually read, whatever
/// sizes the header announces.
///
/// # Errors
/// As [`read_matrix_market`].
pub fn read_matrix_market_from(
    path: &Path,
    reader: impl BufRead,
) -> Result<SparseMatrix, MatrixFileError> {
    let parse = |line: usize, reason: String| MatrixFileError::Parse {
        path: path.to_path_buf(),
        line,
        reason,
    };
    let mut lines = reader.lines().enumerate();
    let (_, banner) = lines.next().ok_or_else(|| parse(1, "empty file".into()))?;
    let banner = banner.map_err(read_err(path, 1))?.to_ascii_lowercase();
    let words: Vec<&str> = banner.split_whitespace().collect();
    if words.len() != 5 || words[0] != "%%matrixmarket" || words[1] != "matrix" {
        return Err(parse(
            1,
            "not a MatrixMarket file (expected '%%MatrixMarket matrix ...')".into(),
        ));
    }
    if words[2] != "coordinate" {
        return Err(parse(
            1,
            format!("'{}' format is not supported; use coordinate", words[2]),
        ));
    }
    let pattern = match words[3] {
        "real" | "integer" | "double" => false,
        "pattern" => true,
        other => {
            return Err(parse(
                1,
                format!("field '{other}' is not supported (real only)"),
            ))
        }
    };
    let symmetry = match words[4] {
        "general" => 0,
        "symmetric" => 1,
        "skew-symmetric" => -1,
        other => return Err(parse(1, format!("symmetry '{other}' is not supported"))),
    };
    let mut size: Option<(usize, usize)> = None;
    let mut triplets: Vec<(usize, usize, f64)> = Vec::new();
    let mut n = 0;
    for (no, line) in lines {
        let no = no + 1;
        let line = line.map_err(read_err(path, no))?;
        let t = line.trim();
        if t.is_empty() || t.starts_with('%') {
            continue;
        }
        let f: Vec<&str> = t.split_whitespace().collect();
        let Some((_, nnz)) = size else {
            let nums: Option<Vec<usize>> = f.iter().map(|s| s.parse().ok()).collect();
            match nums.as_deref() {
                Some(&[r, c, z]) if r == c => {
                    size = Some((r, z));
                    n = r;
                    // The announced count is not trusted for memory: reserve at most ~24 MB.
                    triplets.reserve(z.min(1 << 20));
                }
                Some(&[r, c, _]) => {
                    return Err(parse(
                        no,
                        format!("matrix is {r} x {c}; H and M must be square"),
                    ))
                }
                _ => {
                    return Err(parse(
                        no,
                        format!("bad size line '{t}' (expected 'rows cols entries')"),
                    ))
                }
            }
            continue;
        };
        let want = if pattern { 2 } else { 3 };
        if f.len() < want {
            return Err(parse(no, format!("expected 'row col value', got '{t}'")));
        }
        let idx = |s: &str| -> Result<usize, MatrixFileError> {
            match s.parse::<usize>() {
                Ok(i) if i >= 1 && i <= n => Ok(i - 1),
                _ => Err(parse(no, format!("index '{s}' outside 1..={n}"))),
            }
        };
        let (i, j) = (idx(f[0])?, idx(f[1])?);
        let v = if pattern {
            1.0
        } else {
            match f[2].parse::<f64>() {
                Ok(v) if v.is_finite() => v,
                _ => {
                    return Err(parse(
                        no,
                        format!("value '{}' is not a finite number", f[2]),
                    ))
                }
            }
        };
        triplets.push((i, j, v));
        if symmetry != 0 && i != j {
            triplets.push((j, i, f64::from(symmetry) * v));
        }
        if triplets.len() > nnz.saturating_mul(2) {
            return Err(parse(no, format!("more entries than the {nnz} announced")));
        }
    }
    let Some((_, nnz)) = size else {
        return Err(parse(1, "no size line".into()));
    };
    let stored = triplets
        .iter()
        .filter(|(i, j, _)| symmetry == 0 || i >= j)
        .count();
    if stored != nnz {
        return Err(MatrixFileError::Parse {
            path: path.to_path_buf(),
            line: 0,
            reason: format!("{stored} entries read, {nnz} announced"),
        });
    }
    // Every row of H_w and M has a diagonal entry; a size beyond the entries read means empty
    // rows (a singular pencil) and would make the column pointers alone exhaust memory.
    if n > triplets.len() {
        return Err(MatrixFileError::Parse {
            path: path.to_path_buf(),
            line: 0,
            reason: format!(
                "the matrix is {n} x {n} but has only {} stored entries, so some rows are \
                 empty; check the size line (H_w and M need a non-zero diagonal)",
                triplets.len()
            ),
        });
    }
    if triplets.len() > crate::sparse::MAX_ENTRIES {
        return Err(MatrixFileError::Parse {
            path: path.to_path_buf(),
            line: 0,
            reason: format!(
                "{} stored entries (both triangles) are more than the {} a SparseMatrix \
                 addresses (u32 indices)",
                triplets.len(),
                crate::sparse::MAX_ENTRIES
            ),
        });
    }
    Ok(csc_from_triplets(n, triplets))
}

/// CSC with sorted row indices from triplets (column-major sort, duplicates summed); n and
/// the number of triplets are within u32's range (checked by the caller: n <= triplets).
fn csc_from_triplets(n: usize, mut t: Vec<(usize, usize, f64)>) -> SparseMatrix {
    t.sort_by_key(|a| (a.1, a.0));
    let mut ptr = vec![0u32; n + 1];
    let mut idx = Vec::with_capacity(t.len());
    let mut val: Vec<f64> = Vec::with_capacity(t.len());
    let mut last: Option<(usize, usize)> = None;
    for (i, j, v) in t {
        if last == Some((i, j)) {
            if let Some(x) = val.last_mut() {
                *x += v;
            }
            continue;
        }
        last = Some((i, j));
        idx.push(i as u32);
        val.push(v);
        ptr[j + 1] += 1;
    }
    for j in 0..n {
        ptr[j + 1] += ptr[j];
    }
    from_compressed(n, ptr, idx, val)
}

/// Write a symmetric [`SparseMatrix`] in PETSc's binary matrix format (what `MatView` writes
/// to a binary viewer; `MatLoad` reads it). Row r of a symmetric matrix is its column r.
///
/// # Errors
/// [`MatrixFileError::Io`]; [`MatrixFileError::TooLarge`] beyond PETSc's 32-bit indices.
pub fn write_petsc_binary(path: &Path, a: SparseMatrixRef<'_>) -> Result<(), MatrixFileError> {
    let too_large = |what: &str| MatrixFileError::TooLarge {
        path: path.to_path_buf(),
        reason: format!("{what} exceeds PETSc's 32-bit PetscInt"),
    };
    let n = i32::try_from(a.nrows()).map_err(|_| too_large("the size"))?;
    let sym = a.symbolic();
    let nnz = i32::try_from(sym.row_idx().len()).map_err(|_| too_large("the entry count"))?;
    write_atomically(path, |w| {
        for h in [PETSC_MAT_FILE_CLASSID, n, n, nnz] {
            w.write_all(&h.to_be_bytes())?;
        }
        for j in 0..a.ncols() {
            // Fits: no column holds more than nnz entries.
            w.write_all(&(sym.col_range(j).len() as i32).to_be_bytes())?;
        }
        for &i in sym.row_idx() {
            w.write_all(&(i as i32).to_be_bytes())?;
        }
        for &v in a.val() {
            w.write_all(&v.to_be_bytes())?;
        }
        Ok(())
    })
}

/// Write H_w and M into `dir` (created if missing): `hessian.mtx`, `mass.mtx` and, when
/// `petsc_binary`, `hessian.petsc`, `mass.petsc`. Returns the paths written.
///
/// # Errors
/// [`MatrixFileError`] from any file.
pub fn write_matrices(
    dir: &Path,
    hessian: SparseMatrixRef<'_>,
    mass: SparseMatrixRef<'_>,
    petsc_binary: bool,
) -> Result<Vec<PathBuf>, MatrixFileError> {
    std::fs::create_dir_all(dir).map_err(io_err(dir))?;
    let mut out = Vec::new();
    match write_all(dir, hessian, mass, petsc_binary, &mut out) {
        Ok(()) => Ok(out),
        Err(e) => {
            // All or nothing: a half-written set would pass for a complete export (each file
            // is itself written atomically, so only whole files need removing).
            for p in &out {
                let _ = std::fs::remove_file(p);
            }
            Err(e)
        }
    }
}

/// The files of [`write_matrices`], each pushed to `out` once written.
fn write_all(
    dir: &Path,
    hessian: SparseMatrixRef<'_>,
    mass: SparseMatrixRef<'_>,
    petsc_binary: bool,
    out: &mut Vec<PathBuf>,
) -> Result<(), MatrixFileError> {
    let h = dir.join(HESSIAN_MTX);
    write_matrix_market(
        &h,
        hessian,
        &["freeform weight-space Hessian H_w (Pa m), K x K, rows/columns = kernels"],
    )?;
    out.push(h);
    let m = dir.join(MASS_MTX);
    write_matrix_market(
        &m,
        mass,
        &["freeform consistent RKPM mass M (m^3), K x K; solve H_w c = lambda M c"],
    )?;
    out.push(m);
    if petsc_binary {
        for (name, a) in [(HESSIAN_PETSC, hessian), (MASS_PETSC, mass)] {
            let p = dir.join(name);
            write_petsc_binary(&p, a)?;
            out.push(p);
        }
    }
    Ok(())
}

/// Read `hessian.mtx` and `mass.mtx` from `dir` (as written by [`write_matrices`]).
///
/// # Errors
/// [`MatrixFileError`] from either file.
pub fn read_matrices(dir: &Path) -> Result<(SparseMatrix, SparseMatrix), MatrixFileError> {
    Ok((
        read_matrix_market(&dir.join(HESSIAN_MTX))?,
        read_matrix_market(&dir.join(MASS_MTX))?,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eigen::testing::q1_fem;

    fn same(a: SparseMatrixRef<'_>, b: SparseMatrixRef<'_>) {
        assert_eq!(a.nrows(), b.nrows());
        assert_eq!(a.symbolic().col_ptr(), b.symbolic().col_ptr());
        assert_eq!(a.symbolic().row_idx(), b.symbolic().row_idx());
        // Bit-exact: 17 significant digits round-trip every f64.
        assert_eq!(a.val(), b.val());
    }

    #[test]
    fn matrix_market_round_trip_is_exact() {
        let (h, m) = q1_fem([4, 3, 5], 0.37);
        let dir = tempfile::tempdir().unwrap();
        let paths = write_matrices(dir.path(), h.as_ref(), m.as_ref(), true).unwrap();
        assert_eq!(paths.len(), 4);
        let (h2, m2) = read_matrices(dir.path()).unwrap();
        same(h.as_ref(), h2.as_ref());
        same(m.as_ref(), m2.as_ref());
        // PETSc binary: header, counts, indices, values.
        let bytes = std::fs::read(dir.path().join(HESSIAN_PETSC)).unwrap();
        let nnz = h.symbolic().row_idx().len();
        assert_eq!(bytes.len(), 16 + 4 * h.nrows() + 4 * nnz + 8 * nnz);
        assert_eq!(bytes[..4], PETSC_MAT_FILE_CLASSID.to_be_bytes());
    }

    #[test]
    fn a_failed_export_leaves_no_files() {
        let (h, m) = q1_fem([2, 2, 2], 1.0);
        let dir = tempfile::tempdir().unwrap();
        // A directory where the last file goes: the two .mtx and the first .petsc are
        // written, then the rename onto the directory fails.
        std::fs::create_dir(dir.path().join(MASS_PETSC)).unwrap();
        assert!(write_matrices(dir.path(), h.as_ref(), m.as_ref(), true).is_err());
        for name in [HESSIAN_MTX, MASS_MTX, HESSIAN_PETSC] {
            assert!(!dir.path().join(name).exists(), "{name} left behind");
        }
    }

    #[test]
    fn general_files_with_duplicates_and_bad_files() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.mtx");
        std::fs::write(
            &p,
            "%%MatrixMarket matrix coordinate real general\n% c\n2 2 4\n1 1 1.5\n2 1 -1\n1 2 -1\n1 1 0.5\n",
        )
        .unwrap();
        let a = read_matrix_market(&p).unwrap();
        assert_eq!(crate::sparse::to_dense(a.as_ref())[(0, 0)], 2.0);
        assert_eq!(crate::sparse::to_dense(a.as_ref())[(1, 0)], -1.0);
        for (text, needle) in [
            ("%%MatrixMarket matrix array real general\n2 2\n", "array"),
            (
                "%%MatrixMarket matrix coordinate real general\n2 3 0\n",
                "square",
            ),
            (
                "%%MatrixMarket matrix coordinate real general\n2 2 1\n3 1 1.0\n",
                "outside",
            ),
            (
                "%%MatrixMarket matrix coordinate real general\n2 2 1\n1 1 nan\n",
                "finite",
            ),
            (
                "%%MatrixMarket matrix coordinate real general\n2 2 2\n1 1 1\n",
                "announced",
            ),
            ("hello\n", "not a MatrixMarket"),
        ] {
            std::fs::write(&p, text).unwrap();
            let err = read_matrix_market(&p).unwrap_err().to_string();
            assert!(err.contains(needle), "{text:?}: {err}");
        }
    }
}
