//! Wavefront OBJ reading and writing.
//!
//! Reads `v`, `vt`, `vn` and `f` in every index form (`v`, `v/vt`, `v//vn`, `v/vt/vn`, negative
//! indices), fan-triangulates polygons and keeps `o` / `g` names as groups. The uv layer stays
//! separate from the world vertices (one `vt` index per face corner), which is how garments
//! exported from pattern tools look. Errors name the file and line. Writing keeps uv and groups
//! and can add a per-vertex colour (`v x y z r g b`, read by MeshLab and Blender).
//!
//! A hand-written reader rather than `tobj`: messages must carry line numbers, and face statements
//! must stay traceable to their lines for errors found later (non-manifold edges).

use super::{Group, Mesh, Source, UvLayer};
use crate::error::{Error, Result};
use crate::fsio;
use crate::geom::{Vec2, Vec3};
use std::fmt::Write as _;
use std::path::Path;

/// Reads and validates an OBJ file.
pub fn read_obj(path: &Path) -> Result<Mesh> {
    let bytes = std::fs::read(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let text = String::from_utf8_lossy(&bytes);
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "mesh".into());
    parse_obj(&text, &path.display().to_string(), &name)
}

/// Parses OBJ text; `file` is used in messages, `name` becomes the mesh name.
pub fn parse_obj(text: &str, file: &str, name: &str) -> Result<Mesh> {
    let mut positions: Vec<Vec3> = Vec::new();
    let mut uvs: Vec<Vec2> = Vec::new();
    let mut normals = 0usize;
    // Raw corners: (position index, uv index or none) as written (resolved later).
    let mut tris: Vec<[(i64, Option<i64>); 3]> = Vec::new();
    let mut tri_lines: Vec<u32> = Vec::new();
    let mut groups: Vec<Group> = Vec::new();
    let mut corner_buf: Vec<(i64, Option<i64>)> = Vec::new();
    let err = |line: usize, msg: String| Error::input(format!("{file}:{line}"), msg);

    for (ln0, raw) in text.lines().enumerate() {
        let line = ln0 + 1;
        let content = raw.split('#').next().unwrap_or("");
        let mut it = content.split_whitespace();
        let Some(kw) = it.next() else { continue };
        match kw {
            "v" => {
                let nums = parse_numbers(it, line, file)?;
                if nums.len() < 3 {
                    return Err(err(
                        line,
                        format!("vertex needs 3 coordinates, found {}", nums.len()),
                    ));
                }
                positions.push(Vec3::new(nums[0], nums[1], nums[2]));
            }
            "vt" => {
                let nums = parse_numbers(it, line, file)?;
                if nums.is_empty() {
                    return Err(err(
                        line,
                        "texture coordinate needs at least 1 value".into(),
                    ));
                }
                uvs.push(Vec2::new(nums[0], nums.get(1).copied().unwrap_or(0.0)));
            }
            "vn" => {
                let nums = parse_numbers(it, line, file)?;
                if nums.len() < 3 {
                    return Err(err(
                        line,
                        format!("normal needs 3 coordinates, found {}", nums.len()),
                    ));
                }
                normals += 1;
            }
            "f" => {
                corner_buf.clear();
                for tok in it {
                    corner_buf.push(parse_corner(
                        tok,
                        line,
                        file,
                        positions.len(),
                        uvs.len(),
                        normals,
                    )?);
                }
                if corner_buf.len() < 3 {
                    return Err(err(
                        line,
                        format!("face needs at least 3 vertices, found {}", corner_buf.len()),
                    ));
                }
                for k in 1..corner_buf.len() - 1 {
                    tris.push([corner_buf[0], corner_buf[k], corner_buf[k + 1]]);
                    tri_lines.push(line as u32);
                }
            }
            "o" | "g" => {
                let gname = content.trim_start()[kw.len()..].trim().to_string();
                let first = tris.len() as u32;
                let is_object = kw == "o";
                // An object runs to the next `o`, a group to the next `o` or `g`.
                for g in groups.iter_mut() {
                    if (is_object || !g.is_object) && g.count == u32::MAX {
                        g.count = first - g.first;
                    }
                }
                groups.push(Group {
                    name: if gname.is_empty() {
                        "default".into()
                    } else {
                        gname
                    },
                    first,
                    count: u32::MAX,
                    is_object,
                });
            }
            _ => {}
        }
    }
    for g in groups.iter_mut() {
        if g.count == u32::MAX {
            g.count = tris.len() as u32 - g.first;
        }
    }
    groups.retain(|g| g.count > 0);
    if tris.is_empty() {
        return Err(Error::input(file.to_string(), "no faces"));
    }

    let with_uv = tris
        .iter()
        .filter(|t| t.iter().all(|c| c.1.is_some()))
        .count();
    if with_uv != 0 && with_uv != tris.len() {
        let (i, _) = tris
            .iter()
            .enumerate()
            .find(|(_, t)| t.iter().any(|c| c.1.is_none()))
            .expect("counted above");
        return Err(err(
            tri_lines[i] as usize,
            "face has no texture coordinates but other faces do (mixed uv)".into(),
        ));
    }
    let resolve = |idx: i64, count: usize, what: &str, plural: &str, line: u32| -> Result<u32> {
        if idx >= 1 && (idx as u64) <= count as u64 {
            Ok((idx - 1) as u32)
        } else {
            let noun = if count == 1 { what } else { plural };
            Err(err(
                line as usize,
                format!("{what} index {idx} out of range (the file has {count} {noun})"),
            ))
        }
    };
    let mut triangles = Vec::with_capacity(tris.len());
    let mut uv_tris = Vec::with_capacity(if with_uv > 0 { tris.len() } else { 0 });
    for (t, corners) in tris.iter().enumerate() {
        let line = tri_lines[t];
        let mut tri = [0u32; 3];
        let mut uvt = [0u32; 3];
        for k in 0..3 {
            tri[k] = resolve(corners[k].0, positions.len(), "vertex", "vertices", line)?;
            if let Some(u) = corners[k].1 {
                uvt[k] = resolve(
                    u,
                    uvs.len(),
                    "texture coordinate",
                    "texture coordinates",
                    line,
                )?;
            }
        }
        triangles.push(tri);
        if with_uv > 0 {
            uv_tris.push(uvt);
        }
    }
    let mesh = Mesh {
        name: name.to_string(),
        positions,
        triangles,
        uv: (with_uv > 0).then_some(UvLayer {
            coords: uvs,
            triangles: uv_tris,
        }),
        groups,
        source: Some(Source {
            file: file.to_string(),
            triangle_lines: tri_lines,
        }),
    };
    mesh.validate()?;
    Ok(mesh)
}

fn parse_numbers<'a>(
    it: impl Iterator<Item = &'a str>,
    line: usize,
    file: &str,
) -> Result<Vec<f64>> {
    let mut out = Vec::with_capacity(4);
    for tok in it {
        let x: f64 = tok.parse().map_err(|_| {
            Error::input(format!("{file}:{line}"), format!("'{tok}' is not a number"))
        })?;
        if !x.is_finite() {
            return Err(Error::input(
                format!("{file}:{line}"),
                format!("non-finite number '{tok}'"),
            ));
        }
        out.push(x);
    }
    Ok(out)
}

/// Parses one face corner; negative indices are resolved against the counts so far, positive
/// ones are checked once the whole file is read (returned 1-based).
fn parse_corner(
    tok: &str,
    line: usize,
    file: &str,
    nv: usize,
    nt: usize,
    nn: usize,
) -> Result<(i64, Option<i64>)> {
    let place = || format!("{file}:{line}");
    let mut parts = tok.split('/');
    let idx = |s: &str, count: usize, what: &str| -> Result<i64> {
        let i: i64 = s.parse().map_err(|_| {
            Error::input(
                place(),
                format!("bad {what} index '{s}' in face corner '{tok}'"),
            )
        })?;
        match i {
            0 => Err(Error::input(
                place(),
                format!("{what} index 0 in face corner '{tok}' (OBJ indices start at 1)"),
            )),
            i if i < 0 => {
                let r = count as i64 + i + 1;
                if r < 1 {
                    Err(Error::input(
                        place(),
                        format!("{what} index {i} in face corner '{tok}' reaches before the first {what}"),
                    ))
                } else {
                    Ok(r)
                }
            }
            i => Ok(i),
        }
    };
    let v = idx(parts.next().unwrap_or(""), nv, "vertex")?;
    let t = match parts.next() {
        Some(s) if !s.is_empty() => Some(idx(s, nt, "texture coordinate")?),
        _ => None,
    };
    if let Some(s) = parts.next() {
        if !s.is_empty() {
            let n = idx(s, nn, "normal")?;
            if n as u64 > nn as u64 && n > 0 {
                // Normals are not used; an index past the end is still an error of the file.
                return Err(Error::input(
                    place(),
                    format!("normal index {n} out of range (the file has {nn} normals so far)"),
                ));
            }
        }
    }
    if parts.next().is_some() {
        return Err(Error::input(place(), format!("bad face corner '{tok}'")));
    }
    Ok((v, t))
}

/// Formats a mesh as OBJ text: optional per-vertex colours (`v x y z r g b`, components in
/// `[0, 1]`), the uv layer (if any, as `vt` with `f v/vt`), and `g` lines for groups.
pub fn format_obj(mesh: &Mesh, colors: Option<&[[f32; 3]]>, header: &str) -> String {
    let mut s = String::with_capacity(mesh.positions.len() * 40 + mesh.triangles.len() * 24);
    for l in header.lines() {
        let _ = writeln!(s, "# {l}");
    }
    if !mesh.groups.iter().any(|g| g.is_object) {
        let _ = writeln!(s, "o {}", mesh.name);
    }
    for (i, p) in mesh.positions.iter().enumerate() {
        match colors.and_then(|c| c.get(i)) {
            Some(c) => {
                let _ = writeln!(
                    s,
                    "v {} {} {} {:.4} {:.4} {:.4}",
                    p.x, p.y, p.z, c[0], c[1], c[2]
                );
            }
            None => {
                let _ = writeln!(s, "v {} {} {}", p.x, p.y, p.z);
            }
        }
    }
    if let Some(uv) = &mesh.uv {
        for c in &uv.coords {
            let _ = writeln!(s, "vt {} {}", c.x, c.y);
        }
    }
    let mut g = 0;
    for (t, tri) in mesh.triangles.iter().enumerate() {
        while g < mesh.groups.len() && mesh.groups[g].first as usize == t {
            let kw = if mesh.groups[g].is_object { "o" } else { "g" };
            let _ = writeln!(s, "{kw} {}", mesh.groups[g].name);
            g += 1;
        }
        match &mesh.uv {
            Some(uv) => {
                let u = uv.triangles[t];
                let _ = writeln!(
                    s,
                    "f {}/{} {}/{} {}/{}",
                    tri[0] + 1,
                    u[0] + 1,
                    tri[1] + 1,
                    u[1] + 1,
                    tri[2] + 1,
                    u[2] + 1
                );
            }
            None => {
                let _ = writeln!(s, "f {} {} {}", tri[0] + 1, tri[1] + 1, tri[2] + 1);
            }
        }
    }
    s
}

/// Appends polylines to OBJ text as extra vertices and `l` elements, one object per polyline
/// named `{prefix}{index}`; `first_vertex` is the number of `v` lines already in `text`.
pub fn append_polylines(text: &mut String, first_vertex: usize, prefix: &str, lines: &[Vec<Vec3>]) {
    let mut next = first_vertex + 1;
    for (i, line) in lines.iter().enumerate() {
        if line.len() < 2 {
            continue;
        }
        let _ = writeln!(text, "o {prefix}{i}");
        for p in line {
            let _ = writeln!(text, "v {} {} {}", p.x, p.y, p.z);
        }
        let idx: Vec<String> = (next..next + line.len()).map(|k| k.to_string()).collect();
        let _ = writeln!(text, "l {}", idx.join(" "));
        next += line.len();
    }
}

/// Writes a mesh as OBJ atomically (temporary file, then rename).
pub fn write_obj(
    path: &Path,
    mesh: &Mesh,
    colors: Option<&[[f32; 3]]>,
    header: &str,
) -> Result<()> {
    fsio::write_atomic(path, format_obj(mesh, colors, header).as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(s: &str) -> Result<Mesh> {
        parse_obj(s, "t.obj", "t")
    }

    #[test]
    fn all_index_forms_and_polygons() {
        let m = parse(
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\n\
             o quad\nf 1/1/1 2/2/1 3/3/1 4/4/1\n",
        )
        .unwrap();
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(m.uv.as_ref().unwrap().triangles, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(
            m.groups,
            vec![Group {
                name: "quad".into(),
                first: 0,
                count: 2,
                is_object: true
            }]
        );
        let m = parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf -3//1 -2//1 -1//1\n").unwrap();
        assert_eq!(m.triangles, vec![[0, 1, 2]]);
        assert!(m.uv.is_none());
    }

    #[test]
    fn round_trip_keeps_everything() {
        let text = "v 0 0 0\nv 1 0 0\nv 1 1 0.5\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 2 2\n\
                    g a\nf 1/1 2/2 3/3\ng b\nf 1/1 3/3 4/5\n";
        let m = parse(text).unwrap();
        let back = parse(&format_obj(&m, Some(&[[1.0, 0.0, 0.0]; 4]), "hello")).unwrap();
        assert_eq!(back.positions, m.positions);
        assert_eq!(back.triangles, m.triangles);
        assert_eq!(back.uv, m.uv);
        // The writer names the mesh with an `o` line; the groups follow unchanged.
        assert!(back.groups[0].is_object && back.groups[0].name == "t");
        assert_eq!(back.groups[1..], m.groups[..]);
    }

    #[test]
    fn errors_name_file_and_line() {
        let cases = [
            ("v 0 0 nan\n", "t.obj:1: non-finite number 'nan'"),
            ("v 0 0 inf\n", "t.obj:1: non-finite number 'inf'"),
            ("v 0 0\n", "t.obj:1: vertex needs 3 coordinates"),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n",
                "t.obj:4: vertex index 4 out of range (the file has 3 vertices)",
            ),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n",
                "t.obj:4: vertex index 0",
            ),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -4 1 2\n",
                "t.obj:4: vertex index -4",
            ),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 1 2\n",
                "t.obj:4: degenerate face",
            ),
            (
                "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n",
                "t.obj:4: degenerate face",
            ),
            ("v 0 0 0\n", "t.obj: no faces"),
            ("", "t.obj: no faces"),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n",
                "t.obj:4: face needs at least 3 vertices",
            ),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nf 1/1 2/1 3/1\nf 2 4 3\n",
                "t.obj:7: face has no texture coordinates",
            ),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/2 3/1\n",
                "t.obj:5: texture coordinate index 2 out of range (the file has 1 texture coordinate)",
            ),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/x 2 3\n",
                "t.obj:4: bad texture coordinate index 'x'",
            ),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n",
                "non-manifold edge between vertices 1 and 2",
            ),
        ];
        for (text, want) in cases {
            let got = parse(text).unwrap_err().to_string();
            assert!(
                got.contains(want),
                "input {text:?}: got '{got}', want '{want}'"
            );
        }
    }
}
