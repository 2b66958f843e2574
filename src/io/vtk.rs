//! ParaView output: VTK XML PolyData (`.vtp`, binary appended data) for point sets and
//! triangle meshes, and `.pvd` collections that list frames with their times; readers of both
//! (for `freeform render` and tests).

use crate::geometry::GeometryError;
use crate::{Error, Point3, Result};
use std::io::Write;
use std::path::Path;

/// Point data attached to a `.vtp` file.
pub enum PointData<'a> {
    /// A scalar per point.
    Scalar(&'a str, &'a [f64]),
    /// A 3-vector per point.
    Vector(&'a str, &'a [[f64; 3]]),
    /// A 3 x 3 tensor per point, row-major (9 components, as ParaView reads tensors).
    Tensor(&'a str, &'a [[f64; 9]]),
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
        super::file::check_triangle_indices(n, t)?;
    }
    for d in data {
        let len = match d {
            PointData::Scalar(_, v) => v.len(),
            PointData::Vector(_, v) => v.len(),
            PointData::Tensor(_, v) => v.len(),
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
            PointData::Tensor(name, v) => (name, 9, app.f64s(v.iter().flatten().copied())),
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
    super::file::write_atomically(path, |tmp| {
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
    super::file::write_atomically(path, |tmp| {
        std::fs::write(tmp, s.as_bytes()).map_err(|source| Error::Io {
            path: tmp.to_path_buf(),
            source,
        })
    })
}

/// One `.vtp` file read back: points, triangles (None for a point set) and point data.
#[derive(Debug, Clone, PartialEq)]
pub struct VtpData {
    /// Points, N x 3, metres.
    pub points: Vec<Point3>,
    /// Triangles (indices into `points`) when the file has `Polys`, None for `Verts` only.
    pub triangles: Option<Vec<[u32; 3]>>,
    /// Point data arrays in file order: (name, components, N x components values).
    pub point_data: Vec<(String, usize, Vec<f64>)>,
}

impl VtpData {
    /// The point data array `name` as one scalar per point: the value of a one-component
    /// array, the Euclidean length of a multi-component one (e.g. |displacement|, metres).
    pub fn scalar(&self, name: &str) -> Option<Vec<f64>> {
        let (_, comps, v) = self.point_data.iter().find(|(n, _, _)| n == name)?;
        Some(
            v.chunks(*comps)
                .map(|c| {
                    if c.len() == 1 {
                        c[0]
                    } else {
                        c.iter().map(|x| x * x).sum::<f64>().sqrt()
                    }
                })
                .collect(),
        )
    }
}

/// Largest point or cell count [`read_vtp`] accepts (2^28), so a corrupt header cannot ask
/// for an absurd allocation; the data blocks are also checked against the file's length.
pub const MAX_VTP_ITEMS: usize = 1 << 28;

/// Read a `.vtp` file as [`write_vtp`] writes it: VTK XML PolyData, one piece, binary
/// appended raw data with UInt64 block headers, Float64 points and point data, Int64 (or
/// Int32) connectivity and offsets of `Verts` and/or triangle `Polys`. Other encodings
/// (ASCII, base64, compressed) are a [`GeometryError::Parse`] naming what is unsupported.
pub fn read_vtp(path: &Path) -> Result<VtpData> {
    let bytes = std::fs::read(path).map_err(|source| GeometryError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_vtp(path, &bytes).map_err(|reason| {
        GeometryError::Parse {
            path: path.to_path_buf(),
            reason,
        }
        .into()
    })
}

/// Attribute `name="value"` of an XML tag's text.
fn attribute<'a>(tag: &'a str, name: &str) -> Option<&'a str> {
    let key = format!(" {name}=\"");
    let start = tag.find(&key)? + key.len();
    let len = tag[start..].find('"')?;
    Some(&tag[start..start + len])
}

fn parse_vtp(path: &Path, bytes: &[u8]) -> std::result::Result<VtpData, String> {
    let _ = path;
    const MARK: &[u8] = b"<AppendedData encoding=\"raw\">";
    let at = bytes
        .windows(MARK.len())
        .position(|w| w == MARK)
        .ok_or("no raw <AppendedData> section (only binary appended raw .vtp files are read, as freeform writes them)")?;
    let rest = &bytes[at + MARK.len()..];
    let underscore = rest
        .iter()
        .position(|&b| b == b'_')
        .ok_or("no '_' starting the appended data")?;
    let raw = &rest[underscore + 1..];
    let xml = std::str::from_utf8(&bytes[..at]).map_err(|_| "the XML header is not UTF-8")?;
    if !xml.contains("type=\"PolyData\"") {
        return Err("not a VTK PolyData file".into());
    }
    if let Some(h) = attribute(xml, "header_type") {
        if h != "UInt64" {
            return Err(format!("header_type {h} is not supported (UInt64 only)"));
        }
    }
    if attribute(xml, "compressor").is_some() {
        return Err("compressed appended data is not supported".into());
    }
    if xml.contains("<Piece") && xml.matches("<Piece").count() > 1 {
        return Err("more than one <Piece> is not supported".into());
    }
    let piece = xml.find("<Piece").ok_or("no <Piece>")?;
    let piece_tag = &xml[piece..piece + xml[piece..].find('>').ok_or("unterminated <Piece>")?];
    let count = |name: &str| -> std::result::Result<usize, String> {
        let n: usize = attribute(piece_tag, name)
            .unwrap_or("0")
            .parse()
            .map_err(|_| format!("{name} is not a count"))?;
        if n > MAX_VTP_ITEMS {
            return Err(format!("{name} = {n} is more than {MAX_VTP_ITEMS}"));
        }
        Ok(n)
    };
    let n = count("NumberOfPoints")?;
    let npolys = count("NumberOfPolys")?;
    if count("NumberOfLines")? > 0 || count("NumberOfStrips")? > 0 {
        return Err("lines and triangle strips are not supported".into());
    }
    // The block at `offset`: its UInt64 byte count, then the bytes (checked against the file).
    let block = |offset: usize| -> std::result::Result<&[u8], String> {
        let head = raw.get(offset..offset.saturating_add(8)).ok_or(format!(
            "appended data offset {offset} is past the end of the file"
        ))?;
        let len = u64::from_le_bytes(head.try_into().expect("8 bytes")) as usize;
        raw.get(offset + 8..(offset + 8).saturating_add(len))
            .ok_or(format!(
                "appended block at {offset} ({len} bytes) runs past the end of the file"
            ))
    };
    // Every <DataArray ...> tag with the section it sits in.
    let section_of = |pos: usize| -> &str {
        ["PointData", "Points", "Verts", "Polys", "CellData"]
            .into_iter()
            .filter_map(|s| xml[..pos].rfind(&format!("<{s}")).map(|p| (p, s)))
            .filter(|(p, s)| !xml[*p..pos].contains(&format!("</{s}>")))
            .max_by_key(|(p, _)| *p)
            .map_or("", |(_, s)| s)
    };
    let mut data = VtpData {
        points: Vec::new(),
        triangles: None,
        point_data: Vec::new(),
    };
    let mut polys: (Option<Vec<i64>>, Option<Vec<i64>>) = (None, None);
    for (pos, _) in xml.match_indices("<DataArray") {
        let tag = &xml[pos..pos + xml[pos..].find('>').ok_or("unterminated <DataArray>")?];
        let section = section_of(pos);
        if attribute(tag, "format") != Some("appended") {
            return Err(format!(
                "DataArray format {:?} in <{section}> is not supported (appended only)",
                attribute(tag, "format").unwrap_or("?")
            ));
        }
        let offset: usize = attribute(tag, "offset")
            .and_then(|o| o.parse().ok())
            .ok_or("DataArray without a valid offset")?;
        let ty = attribute(tag, "type").unwrap_or("?");
        let comps: usize = attribute(tag, "NumberOfComponents")
            .unwrap_or("1")
            .parse()
            .map_err(|_| "NumberOfComponents is not a count")?;
        if comps == 0 || comps > 9 {
            return Err(format!(
                "NumberOfComponents = {comps} is out of range 1..=9"
            ));
        }
        let b = block(offset)?;
        let floats = || -> std::result::Result<Vec<f64>, String> {
            match ty {
                "Float64" => Ok(b
                    .chunks_exact(8)
                    .map(|c| f64::from_le_bytes(c.try_into().expect("8")))
                    .collect()),
                "Float32" => Ok(b
                    .chunks_exact(4)
                    .map(|c| f32::from_le_bytes(c.try_into().expect("4")) as f64)
                    .collect()),
                _ => Err(format!(
                    "DataArray type {ty} in <{section}> is not supported (Float64, Float32)"
                )),
            }
        };
        let ints = || -> std::result::Result<Vec<i64>, String> {
            match ty {
                "Int64" => Ok(b
                    .chunks_exact(8)
                    .map(|c| i64::from_le_bytes(c.try_into().expect("8")))
                    .collect()),
                "Int32" => Ok(b
                    .chunks_exact(4)
                    .map(|c| i32::from_le_bytes(c.try_into().expect("4")) as i64)
                    .collect()),
                _ => Err(format!(
                    "DataArray type {ty} in <{section}> is not supported (Int64, Int32)"
                )),
            }
        };
        match section {
            "Points" => {
                let v = floats()?;
                if comps != 3 || v.len() != 3 * n {
                    return Err(format!(
                        "<Points> holds {} values, expected 3 x {n}",
                        v.len()
                    ));
                }
                data.points = v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
            }
            "PointData" => {
                let v = floats()?;
                if v.len() != comps * n {
                    return Err(format!(
                        "point data {:?} holds {} values, expected {comps} x {n}",
                        attribute(tag, "Name").unwrap_or(""),
                        v.len()
                    ));
                }
                data.point_data
                    .push((attribute(tag, "Name").unwrap_or("").to_string(), comps, v));
            }
            "Polys" => match attribute(tag, "Name") {
                Some("connectivity") => polys.0 = Some(ints()?),
                Some("offsets") => polys.1 = Some(ints()?),
                _ => {}
            },
            _ => {}
        }
    }
    if data.points.len() != n {
        return Err(format!("no <Points> array for {n} points"));
    }
    if npolys > 0 {
        let (Some(conn), Some(offs)) = polys else {
            return Err("<Polys> without connectivity and offsets".into());
        };
        if offs.len() != npolys {
            return Err(format!(
                "{} polygon offsets for {npolys} polygons",
                offs.len()
            ));
        }
        let mut tris = Vec::with_capacity(npolys);
        let mut start = 0i64;
        for (f, &end) in offs.iter().enumerate() {
            if end - start != 3 || end as usize > conn.len() {
                return Err(format!(
                    "polygon {f} is not a triangle (only triangles are read)"
                ));
            }
            let t = &conn[start as usize..end as usize];
            if t.iter().any(|&i| i < 0 || i as usize >= n) {
                return Err(format!("triangle {f} = {t:?} refers past the {n} points"));
            }
            tris.push([t[0] as u32, t[1] as u32, t[2] as u32]);
            start = end;
        }
        data.triangles = Some(tris);
    }
    Ok(data)
}

/// Read a `.pvd` collection: (time, dataset path resolved against the `.pvd`'s directory)
/// per `<DataSet>`, in file order.
pub fn read_pvd(path: &Path) -> Result<Vec<(f64, std::path::PathBuf)>> {
    let text = std::fs::read_to_string(path).map_err(|source| GeometryError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let bad = |reason: String| -> Error {
        GeometryError::Parse {
            path: path.to_path_buf(),
            reason,
        }
        .into()
    };
    if !text.contains("type=\"Collection\"") {
        return Err(bad("not a VTK Collection (.pvd) file".into()));
    }
    let dir = path.parent().unwrap_or(Path::new("."));
    let mut out = Vec::new();
    for (i, (pos, _)) in text.match_indices("<DataSet").enumerate() {
        let end = text[pos..]
            .find('>')
            .ok_or_else(|| bad(format!("DataSet {i} is not terminated")))?;
        let tag = &text[pos..pos + end];
        let t: f64 = attribute(tag, "timestep")
            .unwrap_or("0")
            .parse()
            .map_err(|_| bad(format!("DataSet {i} has a timestep that is not a number")))?;
        let file = attribute(tag, "file").ok_or_else(|| bad(format!("DataSet {i} has no file")))?;
        out.push((t, dir.join(xml_unescape(file))));
    }
    Ok(out)
}

fn xml_unescape(s: &str) -> String {
    s.replace("&quot;", "\"")
        .replace("&gt;", ">")
        .replace("&lt;", "<")
        .replace("&amp;", "&")
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
        // Read back: the same points, triangles and data; the pvd's paths resolved.
        let back = read_vtp(&path).unwrap();
        assert_eq!(back.points, pts.to_vec());
        assert_eq!(back.triangles, Some(vec![[0, 1, 2]]));
        assert_eq!(back.point_data[0].0, "displacement");
        assert_eq!(back.scalar("displacement").unwrap()[1], 0.0);
        let frames = read_pvd(&pvd).unwrap();
        assert_eq!(
            frames,
            vec![
                (0.0, dir.path().join("m.vtp")),
                (0.01, dir.path().join("m2.vtp"))
            ]
        );
        let cloud = dir.path().join("c.vtp");
        write_vtp(
            &cloud,
            &pts,
            None,
            &[PointData::Scalar("s", &[1.0, 2.0, 3.0])],
        )
        .unwrap();
        let back = read_vtp(&cloud).unwrap();
        assert_eq!(
            (back.scalar("s"), back.triangles),
            (Some(vec![1.0, 2.0, 3.0]), None)
        );
        // Truncated files are errors with the path, not panics.
        let bytes = std::fs::read(&path).unwrap();
        for cut in [10, bytes.len() / 2, bytes.len() - 40] {
            std::fs::write(&cloud, &bytes[..cut]).unwrap();
            let e = read_vtp(&cloud).unwrap_err().to_string();
            assert!(e.contains("c.vtp"), "{e}");
        }
    }
}
