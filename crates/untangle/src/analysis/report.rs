//! The analysis as a JSON-serialisable report (`untangle check --json`).
//!
//! Indices are 0-based into the concatenation of all inputs in the order given (triangles in the
//! order faces appear, polygons fan-triangulated; vertices in `v` order).

use super::{Analysis, AnalysisMesh, ObjectKind, Region};
use serde::Serialize;
use std::collections::BTreeMap;

/// One input object in the report.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ObjectReport {
    /// Name.
    pub name: String,
    /// `cloth` or `obstacle`.
    pub kind: ObjectKind,
    /// First vertex index and count.
    pub vertices: [u32; 2],
    /// First triangle index and count.
    pub triangles: [u32; 2],
    /// Sewing panels (connected components of the uv layer; 1 without uv).
    pub panels: Option<usize>,
    /// World vertices with several uv copies.
    pub seam_vertices: Option<usize>,
}

/// Intersecting pairs between two objects (the same object twice: self-intersections).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct PairGroup {
    /// The two objects.
    pub objects: [u32; 2],
    /// `self`, `cloth-cloth` or `cloth-obstacle`.
    pub relation: &'static str,
    /// Number of intersecting triangle pairs.
    pub pairs: usize,
}

/// One parameter-space path.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct PathReport {
    /// Kind after splitting (CLOSED, LL, BB, BI, II, BLI, ...).
    pub kind: &'static str,
    /// `EIGHT` or `CROSS` if the path came from splitting one.
    pub split_from: Option<&'static str>,
    /// Object holding the path.
    pub object: u32,
    /// Whether closed.
    pub closed: bool,
    /// End kinds (`B`/`I`) of an open path.
    pub ends: Option<[super::EndKind; 2]>,
    /// Loop vertices on the path.
    pub loop_vertices: Vec<u32>,
    /// Index of the corresponding path.
    pub corresponds_to: u32,
    /// Number of segments (pieces) along the path.
    pub segments: usize,
    /// Index of the tanglement.
    pub tanglement: u32,
    /// Number of vertices in its inside region (partitioning paths that separate their mesh).
    pub inside_vertices: Option<usize>,
    /// False for a partitioning kind that does not separate its mesh.
    pub separating: bool,
    /// Whether the inside region is a winding region (ours,
    /// [`super::regions::RegionFinder::winding_region`]; only with
    /// [`super::Options::winding_regions`]).
    pub winding_region: bool,
    /// Where the path is, in world space: its first loop vertex, or the centroid of the
    /// triangle holding its first piece.
    pub location: [f64; 3],
}

/// One tanglement.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct TanglementReport {
    /// Category (CLOSED, EIGHT, LL, BLI, CROSS, BBII, BIBI).
    pub kind: String,
    /// Paths.
    pub paths: Vec<u32>,
    /// Objects involved.
    pub objects: [u32; 2],
    /// Loop vertices.
    pub loop_vertices: Vec<u32>,
}

/// The whole report.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Report {
    /// Tool version.
    pub version: &'static str,
    /// Inputs.
    pub objects: Vec<ObjectReport>,
    /// Total triangles.
    pub triangles: usize,
    /// Total vertices.
    pub vertices: usize,
    /// Number of intersecting triangle pairs.
    pub intersecting_triangle_pairs: usize,
    /// Pairs per object pair.
    pub pairs_by_objects: Vec<PairGroup>,
    /// Sorted triangles that intersect another triangle.
    pub intersecting_triangles: Vec<u32>,
    /// Number of edge-triangle crossings.
    pub crossings: usize,
    /// Paths.
    pub paths: Vec<PathReport>,
    /// Paths by kind.
    pub paths_by_kind: BTreeMap<String, usize>,
    /// Tanglements.
    pub tanglements: Vec<TanglementReport>,
    /// Tanglements by category.
    pub tanglements_by_kind: BTreeMap<String, usize>,
    /// Red vertices.
    pub red_vertices: usize,
    /// Red edges.
    pub red_edges: usize,
    /// Red triangles.
    pub red_triangles: usize,
    /// Out-most red vertices.
    pub outmost_red_vertices: usize,
    /// Red* triangles.
    pub red_star_triangles: usize,
    /// Timings in milliseconds.
    pub timing_ms: super::Timing,
}

impl Report {
    /// Builds the report (`pos`: the positions the analysis ran on).
    pub fn new(mesh: &AnalysisMesh, pos: &[crate::geom::Vec3], a: &Analysis) -> Report {
        let location = |p: &super::Path| -> [f64; 3] {
            let x = match p.loop_vertices().first() {
                Some(&v) => pos[v as usize],
                None => {
                    let piece = p.pieces()[0];
                    let t = a.segments[(piece / 2) as usize].triangles[(piece % 2) as usize];
                    mesh.triangles[t as usize]
                        .iter()
                        .map(|&v| pos[v as usize])
                        .sum::<crate::geom::Vec3>()
                        / 3.0
                }
            };
            [x.x, x.y, x.z]
        };
        let mut groups: BTreeMap<[u32; 2], usize> = BTreeMap::new();
        for s in &a.segments {
            let o0 = mesh.object_of_triangle[s.triangles[0] as usize];
            let o1 = mesh.object_of_triangle[s.triangles[1] as usize];
            *groups.entry([o0.min(o1), o0.max(o1)]).or_default() += 1;
        }
        let pairs_by_objects = groups
            .into_iter()
            .map(|(objects, pairs)| {
                let kinds = objects.map(|o| mesh.objects[o as usize].kind);
                let relation = if objects[0] == objects[1] {
                    "self"
                } else if kinds.contains(&ObjectKind::Obstacle) {
                    "cloth-obstacle"
                } else {
                    "cloth-cloth"
                };
                PairGroup {
                    objects,
                    relation,
                    pairs,
                }
            })
            .collect();
        let paths: Vec<PathReport> = a
            .paths
            .iter()
            .zip(&a.regions)
            .enumerate()
            .map(|(i, (p, r))| {
                (
                    p,
                    r,
                    a.winding_region_paths.binary_search(&(i as u32)).is_ok(),
                )
            })
            .map(|(p, r, winding)| PathReport {
                kind: p.kind.name(),
                split_from: p.split_from.map(|k| k.name()),
                object: p.object,
                closed: p.closed,
                ends: p.ends,
                loop_vertices: p.loop_vertices().to_vec(),
                corresponds_to: p.corresponds_to,
                segments: p.pieces().len(),
                tanglement: p.tanglement,
                inside_vertices: match r {
                    Region::Inside(v) => Some(v.len()),
                    _ => None,
                },
                separating: !(matches!(r, Region::NotSeparating)
                    || winding && p.kind.is_partitioning()),
                winding_region: winding,
                location: location(p),
            })
            .collect();
        let mut paths_by_kind = BTreeMap::new();
        for p in &paths {
            *paths_by_kind.entry(p.kind.to_string()).or_default() += 1;
        }
        let mut tanglements_by_kind = BTreeMap::new();
        for t in &a.tanglements {
            *tanglements_by_kind.entry(t.kind.to_string()).or_default() += 1;
        }
        Report {
            version: env!("CARGO_PKG_VERSION"),
            objects: mesh
                .objects
                .iter()
                .map(|o| ObjectReport {
                    name: o.name.clone(),
                    kind: o.kind,
                    vertices: [o.vertices.start, o.vertices.end - o.vertices.start],
                    triangles: [o.triangles.start, o.triangles.end - o.triangles.start],
                    panels: None,
                    seam_vertices: None,
                })
                .collect(),
            triangles: mesh.triangles.len(),
            vertices: mesh.num_vertices(),
            intersecting_triangle_pairs: a.segments.len(),
            pairs_by_objects,
            intersecting_triangles: a.intersecting_triangles(),
            crossings: a.crossings.len(),
            paths,
            paths_by_kind,
            tanglements: a
                .tanglements
                .iter()
                .map(|t| TanglementReport {
                    kind: t.kind.to_string(),
                    paths: t.paths.to_vec(),
                    objects: t.objects,
                    loop_vertices: t.loop_vertices.clone(),
                })
                .collect(),
            tanglements_by_kind,
            red_vertices: a.coloring.num_red_vertices(),
            red_edges: a.coloring.num_red_edges(),
            red_triangles: a.coloring.num_red_triangles(),
            outmost_red_vertices: a.coloring.outmost_red.len(),
            red_star_triangles: a.coloring.red_star.len(),
            timing_ms: a.timing,
        }
    }

    /// Adds panel and seam counts of the cloth objects (`parts` in object order).
    pub fn with_garment_info(mut self, parts: &[&crate::mesh::Mesh]) -> Report {
        for (o, m) in self.objects.iter_mut().zip(parts) {
            if o.kind != ObjectKind::Cloth {
                continue;
            }
            if let Ok(g) = crate::mesh::Garment::new((*m).clone()) {
                o.panels = Some(g.num_panels);
                o.seam_vertices = Some(g.num_seam_vertices());
            }
        }
        self
    }

    /// Pretty JSON text.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("report serialises")
    }
}
