//! Triangle meshes as garments arrive: world positions, triangles over world vertices, and a
//! separate uv layer (OBJ style, one uv triple per triangle) whose connected components are the
//! sewing panels. A world vertex with several uv copies lies on a seam.

pub mod garment;
pub mod obj;
pub mod subdivide;
pub mod topology;

pub use garment::{Garment, UvSource};
pub use topology::Topology;

use crate::error::{Error, Result};
use crate::geom::{Vec2, Vec3};

/// A named run of consecutive triangles (an OBJ `o` or `g` block).
#[derive(Clone, Debug, PartialEq)]
pub struct Group {
    /// The object or group name.
    pub name: String,
    /// First triangle of the run.
    pub first: u32,
    /// Number of triangles.
    pub count: u32,
    /// An OBJ object (`o`) rather than a group (`g`): objects are analysed as separate pieces.
    pub is_object: bool,
}

/// The uv layer: coordinates and, for every triangle, the indices of its three corners' uvs.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct UvLayer {
    /// uv coordinates (OBJ `vt`).
    pub coords: Vec<Vec2>,
    /// Per triangle, the uv index of each corner (parallel to [`Mesh::triangles`]).
    pub triangles: Vec<[u32; 3]>,
}

/// A triangle mesh: world positions, triangles, optional uv layer and names.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Name (file stem or `o` name) used in messages and reports.
    pub name: String,
    /// World positions (OBJ `v`).
    pub positions: Vec<Vec3>,
    /// Triangles over world vertices, counter-clockwise as given.
    pub triangles: Vec<[u32; 3]>,
    /// The uv layer, when the input had one.
    pub uv: Option<UvLayer>,
    /// Named triangle runs (`o` / `g`).
    pub groups: Vec<Group>,
    /// For meshes read from a file: the file's name and each triangle's line, for messages.
    pub source: Option<Source>,
}

/// Where a mesh came from, so that errors found later can still name a file and line.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Source {
    /// The file as given by the user.
    pub file: String,
    /// The line of the `f` statement each triangle came from.
    pub triangle_lines: Vec<u32>,
}

impl Mesh {
    /// A mesh from positions and triangles (no uv), validated.
    pub fn new(
        name: impl Into<String>,
        positions: Vec<Vec3>,
        triangles: Vec<[u32; 3]>,
    ) -> Result<Mesh> {
        let m = Mesh {
            name: name.into(),
            positions,
            triangles,
            ..Default::default()
        };
        m.validate()?;
        Ok(m)
    }

    /// The mesh's OBJ objects (`o` blocks) as separate meshes, so several garments in one file are
    /// analysed as separate pieces. Triangles before the first `o` form an object of their own.
    /// When objects share a vertex they are one surface and the mesh is returned whole.
    pub fn split_objects(&self) -> Vec<Mesh> {
        let objects: Vec<&Group> = self.groups.iter().filter(|g| g.is_object).collect();
        let mut ranges: Vec<(String, u32, u32)> = Vec::new();
        let first = objects.first().map(|g| g.first).unwrap_or(0);
        if first > 0 {
            ranges.push((self.name.clone(), 0, first));
        }
        for (i, g) in objects.iter().enumerate() {
            let end = objects
                .get(i + 1)
                .map(|n| n.first)
                .unwrap_or(self.triangles.len() as u32);
            if end > g.first {
                ranges.push((g.name.clone(), g.first, end));
            }
        }
        if ranges.len() <= 1 {
            return vec![self.clone()];
        }
        let mut owner = vec![u32::MAX; self.positions.len()];
        for (k, r) in ranges.iter().enumerate() {
            for t in &self.triangles[r.1 as usize..r.2 as usize] {
                for &v in t {
                    if owner[v as usize] != u32::MAX && owner[v as usize] != k as u32 {
                        return vec![self.clone()];
                    }
                    owner[v as usize] = k as u32;
                }
            }
        }
        ranges
            .iter()
            .map(|(name, a, b)| self.sub_mesh(name, *a, *b))
            .collect()
    }

    /// Triangles `a..b` as a mesh of their own (vertices and uvs renumbered in order of use).
    fn sub_mesh(&self, name: &str, a: u32, b: u32) -> Mesh {
        let renumber = |tris: &[[u32; 3]]| {
            let mut map = std::collections::BTreeMap::new();
            for &v in tris.iter().flatten() {
                let n = map.len() as u32;
                map.entry(v).or_insert(n);
            }
            map
        };
        let tris = &self.triangles[a as usize..b as usize];
        let map = renumber(tris);
        let mut positions = vec![Vec3::zeros(); map.len()];
        for (&old, &new) in &map {
            positions[new as usize] = self.positions[old as usize];
        }
        let uv = self.uv.as_ref().map(|uv| {
            let ut = &uv.triangles[a as usize..b as usize];
            let umap = renumber(ut);
            let mut coords = vec![Vec2::zeros(); umap.len()];
            for (&old, &new) in &umap {
                coords[new as usize] = uv.coords[old as usize];
            }
            UvLayer {
                coords,
                triangles: ut.iter().map(|t| t.map(|i| umap[&i])).collect(),
            }
        });
        Mesh {
            name: name.to_string(),
            positions,
            triangles: tris.iter().map(|t| t.map(|v| map[&v])).collect(),
            uv,
            groups: self
                .groups
                .iter()
                .filter(|g| !g.is_object && g.first >= a && g.first < b)
                .map(|g| Group {
                    name: g.name.clone(),
                    first: g.first - a,
                    count: g.count.min(b - g.first),
                    is_object: false,
                })
                .collect(),
            source: self.source.as_ref().map(|s| Source {
                file: s.file.clone(),
                triangle_lines: s.triangle_lines[a as usize..b as usize].to_vec(),
            }),
        }
    }

    /// A human-readable location for triangle `t`: `file:line` or `mesh 'name', triangle t`.
    pub fn triangle_place(&self, t: usize) -> String {
        match &self.source {
            Some(s) if t < s.triangle_lines.len() => format!("{}:{}", s.file, s.triangle_lines[t]),
            _ => format!("mesh '{}', triangle {}", self.name, t),
        }
    }

    /// A human-readable location for the whole mesh.
    pub fn place(&self) -> String {
        match &self.source {
            Some(s) => s.file.clone(),
            None => format!("mesh '{}'", self.name),
        }
    }

    /// Checks everything the analysis relies on: at least one triangle, finite coordinates,
    /// in-range indices, no repeated vertex within a triangle, no exactly zero-area triangle, uv
    /// layer consistent with the triangles, and manifold edges (at most two triangles per edge).
    pub fn validate(&self) -> Result<()> {
        if self.triangles.is_empty() {
            return Err(Error::input(self.place(), "no faces"));
        }
        for (i, p) in self.positions.iter().enumerate() {
            if !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) {
                return Err(Error::input(
                    self.place(),
                    format!("vertex {} has a non-finite coordinate", i + 1),
                ));
            }
        }
        let n = self.positions.len() as u64;
        for (t, tri) in self.triangles.iter().enumerate() {
            if let Some(&bad) = tri.iter().find(|&&v| v as u64 >= n) {
                return Err(Error::input(
                    self.triangle_place(t),
                    format!(
                        "vertex index {} out of range (the mesh has {} vertices)",
                        bad as u64 + 1,
                        n
                    ),
                ));
            }
            if tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
                return Err(Error::input(
                    self.triangle_place(t),
                    format!("degenerate face: vertex {} repeated", repeated(tri) + 1),
                ));
            }
            let [a, b, c] = tri.map(|v| self.positions[v as usize]);
            if is_collinear(&a, &b, &c) {
                return Err(Error::input(
                    self.triangle_place(t),
                    "degenerate face: its three vertices are collinear (zero area)",
                ));
            }
        }
        if let Some(uv) = &self.uv {
            if uv.triangles.len() != self.triangles.len() {
                return Err(Error::input(
                    self.place(),
                    format!(
                        "uv layer has {} triangles but the mesh has {}",
                        uv.triangles.len(),
                        self.triangles.len()
                    ),
                ));
            }
            let m = uv.coords.len() as u64;
            for (i, c) in uv.coords.iter().enumerate() {
                if !(c.x.is_finite() && c.y.is_finite()) {
                    return Err(Error::input(
                        self.place(),
                        format!("uv {} has a non-finite coordinate", i + 1),
                    ));
                }
            }
            for (t, tri) in uv.triangles.iter().enumerate() {
                if let Some(&bad) = tri.iter().find(|&&v| v as u64 >= m) {
                    return Err(Error::input(
                        self.triangle_place(t),
                        format!(
                            "uv index {} out of range (the mesh has {} uvs)",
                            bad as u64 + 1,
                            m
                        ),
                    ));
                }
            }
        }
        Topology::new(self)?;
        Ok(())
    }
}

fn repeated(t: &[u32; 3]) -> u32 {
    if t[0] == t[1] || t[0] == t[2] {
        t[0]
    } else {
        t[1]
    }
}

/// Exact collinearity test: all three axis-plane projections have zero orientation.
fn is_collinear(a: &Vec3, b: &Vec3, c: &Vec3) -> bool {
    let o = |u: usize, v: usize| {
        robust::orient2d(
            robust::Coord { x: a[u], y: a[v] },
            robust::Coord { x: b[u], y: b[v] },
            robust::Coord { x: c[u], y: c[v] },
        )
    };
    o(0, 1) == 0.0 && o(1, 2) == 0.0 && o(2, 0) == 0.0
}

#[cfg(test)]
mod tests {
    use super::obj::parse_obj;

    #[test]
    fn objects_split_into_separate_meshes() {
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 0 0\nv 6 0 0\nv 5 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n\
                    o first\nf 1/1 2/2 3/3\no second\ng part\nf 4/1 5/2 6/3\n";
        let m = parse_obj(text, "t.obj", "t").unwrap();
        let parts = m.split_objects();
        assert_eq!(parts.len(), 2);
        assert_eq!(parts[0].name, "first");
        assert_eq!(parts[1].positions[0], m.positions[3]);
        assert_eq!(parts[1].triangles, vec![[0, 1, 2]]);
        assert_eq!(parts[1].uv.as_ref().unwrap().coords.len(), 3);
        assert_eq!(parts[1].groups[0].name, "part");
        assert_eq!(parts[1].triangle_place(0), "t.obj:14");
        // Objects sharing a vertex stay one surface.
        let shared = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\no a\nf 1 2 3\no b\nf 2 4 3\n";
        assert_eq!(
            parse_obj(shared, "s.obj", "s")
                .unwrap()
                .split_objects()
                .len(),
            1
        );
    }
}
