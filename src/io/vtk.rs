//! ParaView output: VTK XML PolyData (`.vtp`, binary appended data) for point sets and
//! triangle meshes, and `.pvd` collections that list frames with their times.

use crate::{Error, Point3, Result};
use std::io::Write;
use std::path::Path;

/// Point data attached to a `.vtp` file.
pub enum PointData<'a> {
    /// A scalar per point.
    Scalar(&'a str, &'a [f64]),
    /// A 3-vector per point.
    Vector(&'a str, &'a [[f64; 3]]),
}

struct Appended {
    bytes: Vec<u8>,
}

impl Appended {
    /// Append one block (UInt64 byte count, then the data); returns its offset.
    fn push(&mut self, data: &[u8]) -> usize {
        let offset = self.bytes.len();
        self.bytes
            .extend_from_slice(&(data.len() as u64).to_le_bytes());
        self.bytes.extend_from_slice(data);
        offset
    }
    fn f64s(&mut self, v: impl Iterator<Item = f64>) -> usize {
        let d: Vec<u8> = v.flat_map(|x| x.to_le_bytes()).collect();
        self.push(&d)
    }
    fn i64s(&mut self, v: impl Iterator<Item = i64>) -> usize {
        let d: Vec<u8> = v.flat_map(|x| x.to_le_bytes()).collect();
        self.push(&d)
    }
}

/// Write `points` (N x 3, metres) as a `.vtp` file, with vertex cells when `triangles` is
/// None (a point cloud) or the triangles (indices into `points`) otherwise, and point data.
/// Written atomically.
pub fn write_vtp(
    path: &Path,
    points: &[Point3],
    triangles: Option<&[[u32; 3]]>,
    data: &[PointData],
) -> Result<()> {
    let n = points.len();
    if let Some(t) = triangles {
        super::check_triangle_indices(n, t)?;
    }
    for d in data {
        let len = match d {
            PointData::Scalar(_, v) => v.len(),
            PointData::Vector(_, v) => v.len(),
        };
        if len != n {
            return Err(Error::LengthMismatch {
                what: "VTK point data",
                expected: n,
                got: len,
            });
        }
    }
    let mut app = Appended { bytes: Vec::new() };
    let pts = app.f64s(points.iter().flatten().copied());
    let mut pd = String::new();
    for d in data {
        let (name, comps, off) = match d {
            PointData::Scalar(name, v) => (name, 1, app.f64s(v.iter().copied())),
            PointData::Vector(name, v) => (name, 3, app.f64s(v.iter().flatten().copied())),
        };
        pd.push_str(&format!(
            "        <DataArray type=\"Float64\" Name=\"{}\" NumberOfComponents=\"{comps}\" format=\"appended\" offset=\"{off}\"/>\n",
            xml_escape(name)
        ));
    }
    let (cells_tag, ncells, conn, offs) = match triangles {
        None => ("Verts", n, app.i64s(0..n as i64), app.i64s(1..=n as i64)),
        Some(t) => (
            "Polys",
            t.len(),
            app.i64s(t.iter().flatten().map(|&i| i as i64)),
            app.i64s((1..=t.len() as i64).map(|i| 3 * i)),
        ),
    };
    let (nverts, npolys) = if triangles.is_none() {
        (ncells, 0)
    } else {
        (0, ncells)
    };
    let header = format!(
        "<?xml version=\"1.0\"?>\n\
<VTKFile type=\"PolyData\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n\
  <PolyData>\n\
    <Piece NumberOfPoints=\"{n}\" NumberOfVerts=\"{nverts}\" NumberOfLines=\"0\" NumberOfStrips=\"0\" NumberOfPolys=\"{npolys}\">\n\
      <PointData>\n{pd}      </PointData>\n\
      <Points>\n\
        <DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"appended\" offset=\"{pts}\"/>\n\
      </Points>\n\
      <{cells_tag}>\n\
        <DataArray type=\"Int64\" Name=\"connectivity\" format=\"appended\" offset=\"{conn}\"/>\n\
        <DataArray type=\"Int64\" Name=\"offsets\" format=\"appended\" offset=\"{offs}\"/>\n\
      </{cells_tag}>\n\
    </Piece>\n\
  </PolyData>\n\
  <AppendedData encoding=\"raw\">\n_"
    );
    super::write_atomically(path, |tmp| {
        let io = |source| Error::Io {
            path: tmp.to_path_buf(),
            source,
        };
        let mut f = std::io::BufWriter::new(std::fs::File::create(tmp).map_err(io)?);
        f.write_all(header.as_bytes()).map_err(io)?;
        f.write_all(&app.bytes).map_err(io)?;
        f.write_all(b"\n  </AppendedData>\n</VTKFile>\n")
            .map_err(io)?;
        f.flush().map_err(io)
    })
}

/// Write a `.pvd` collection listing `(time in seconds, file path relative to the .pvd)`.
pub fn write_pvd(path: &Path, frames: &[(f64, String)]) -> Result<()> {
    let mut s = String::from(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n  <Collection>\n",
    );
    for (t, file) in frames {
        s.push_str(&format!(
            "    <DataSet timestep=\"{t:.9e}\" group=\"\" part=\"0\" file=\"{}\"/>\n",
            xml_escape(file)
        ));
    }
    s.push_str("  </Collection>\n</VTKFile>\n");
    super::write_atomically(path, |tmp| {
        std::fs::write(tmp, s.as_bytes()).map_err(|source| Error::Io {
            path: tmp.to_path_buf(),
            source,
        })
    })
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Read the appended block at `offset` (after the '_') as little-endian f64 or i64 bytes.
    fn block(raw: &[u8], offset: usize) -> &[u8] {
        let len = u64::from_le_bytes(raw[offset..offset + 8].try_into().unwrap()) as usize;
        &raw[offset + 8..offset + 8 + len]
    }

    fn offsets(xml: &str) -> Vec<usize> {
        xml.match_indices("offset=\"")
            .map(|(i, _)| {
                let rest = &xml[i + 8..];
                rest[..rest.find('"').unwrap()].parse().unwrap()
            })
            .collect()
    }

    #[test]
    fn vtp_round_trips_points_cells_and_data() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.vtp");
        let pts = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.5, -2.0]];
        let disp = [[0.1, 0.2, 0.3], [0.0; 3], [-1.0, 2.0, 3.0]];
        write_vtp(
            &path,
            &pts,
            Some(&[[0, 1, 2]]),
            &[PointData::Vector("displacement", &disp)],
        )
        .unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let start = bytes.windows(2).position(|w| w == b"\n_").unwrap() + 2;
        let xml = String::from_utf8_lossy(&bytes[..start]).to_string();
        assert!(xml.contains("NumberOfPoints=\"3\"") && xml.contains("NumberOfPolys=\"1\""));
        let raw = &bytes[start..];
        let off = offsets(&xml);
        // Order in the header: displacement, points, connectivity, offsets.
        let f = |o: usize| -> Vec<f64> {
            block(raw, o)
                .chunks(8)
                .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
                .collect()
        };
        let i = |o: usize| -> Vec<i64> {
            block(raw, o)
                .chunks(8)
                .map(|c| i64::from_le_bytes(c.try_into().unwrap()))
                .collect()
        };
        assert_eq!(
            f(off[0]),
            disp.iter().flatten().copied().collect::<Vec<_>>()
        );
        assert_eq!(f(off[1]), pts.iter().flatten().copied().collect::<Vec<_>>());
        assert_eq!(i(off[2]), vec![0, 1, 2]);
        assert_eq!(i(off[3]), vec![3]);
        assert!(bytes.ends_with(b"</VTKFile>\n"));
        // Bad input: a triangle past the points, mismatched data.
        assert!(write_vtp(&path, &pts, Some(&[[0, 1, 3]]), &[]).is_err());
        assert!(write_vtp(&path, &pts, None, &[PointData::Scalar("s", &[1.0])]).is_err());
        // No temporary files are left behind.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        let pvd = dir.path().join("a.pvd");
        write_pvd(&pvd, &[(0.0, "m.vtp".into()), (0.01, "m2.vtp".into())]).unwrap();
        let s = std::fs::read_to_string(&pvd).unwrap();
        assert_eq!(s.matches("<DataSet").count(), 2);
        assert!(s.contains("file=\"m2.vtp\""));
    }
}
