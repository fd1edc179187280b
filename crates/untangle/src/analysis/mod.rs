//! Global intersection analysis (Wicke et al. 2006, Sec. 4; Cha & Ko 2022, Sec. 3).
//!
//! A pure function of positions and connectivity: broad phase (BVH), crossings with exact,
//! symbolically perturbed predicates, segments, parameter-space paths with correspondences and
//! kinds, inside regions of partitioning paths, and the red/green colouring. Results are identical
//! for every run and thread count.

pub mod coloring;
pub mod crossings;
pub mod culling;
pub mod curves;
pub mod input;
pub mod paths;
pub mod regions;
pub mod report;
pub mod reporters;
pub mod segments;
pub mod winding;

pub use coloring::Coloring;
pub use crossings::Crossing;
pub use input::{AnalysisMesh, Object, ObjectKind};
pub use paths::{EndKind, Path, PathKind, Tanglement};
pub use regions::Region;
pub use reporters::Reporters;
pub use segments::{End, Inconsistency, Segment};

use crate::geom::Vec3;
use std::time::Instant;

/// Wall-clock time of each phase, in milliseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Timing {
    /// Triangle boxes and BVH build.
    pub broad_phase: f64,
    /// Crossing tests (includes the BVH traversal).
    pub crossings: f64,
    /// Segments, paths, kinds.
    pub paths: f64,
    /// Inside regions and colouring.
    pub regions: f64,
    /// Everything.
    pub total: f64,
}

/// The result of the analysis.
#[derive(Clone, Debug)]
pub struct Analysis {
    /// Every edge-triangle crossing, sorted.
    pub crossings: Vec<Crossing>,
    /// Every intersecting triangle pair with its segment.
    pub segments: Vec<Segment>,
    /// For each crossing, the segments ending there.
    pub segments_of_crossing: Vec<[u32; 2]>,
    /// Parameter-space paths (EIGHT and CROSS already split).
    pub paths: Vec<Path>,
    /// Tanglements: one per world-space intersection curve, with Cha & Ko's category.
    pub tanglements: Vec<Tanglement>,
    /// Inside region of each path.
    pub regions: Vec<Region>,
    /// The paths (ascending) whose region is a winding region ([`Options::winding_regions`]).
    pub winding_region_paths: Vec<u32>,
    /// Red/green colouring of the cloth.
    pub coloring: Coloring,
    /// Phase timings.
    pub timing: Timing,
}

impl Analysis {
    /// Whether anything intersects.
    pub fn is_clean(&self) -> bool {
        self.segments.is_empty()
    }

    /// Sorted indices of triangles that intersect another triangle.
    pub fn intersecting_triangles(&self) -> Vec<u32> {
        let mut v: Vec<u32> = self.segments.iter().flat_map(|s| s.triangles).collect();
        v.sort_unstable();
        v.dedup();
        v
    }

    /// The triangle piece `piece` of a path lies in ([`paths::piece_triangle`]).
    #[inline]
    pub fn piece_triangle(&self, piece: u32) -> u32 {
        self.segments[(piece / 2) as usize].triangles[(piece % 2) as usize]
    }

    /// Sorted, distinct loop vertices of all paths (Wicke et al. 2006, Sec. 4.1: where a path
    /// meets itself or its corresponding path).
    pub fn loop_vertices(&self) -> Vec<u32> {
        let mut v: Vec<u32> = self
            .paths
            .iter()
            .flat_map(|p| p.loop_vertices().iter().copied())
            .collect();
        v.sort_unstable();
        v.dedup();
        v
    }
}

/// Choices beyond the papers' defaults.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Options {
    /// Colour the cone regions of BLI paths red as well (Wicke's heuristic, Sec. 4.2). BLI paths
    /// are outside Cha & Ko's method; their regions are always computed and reported, and only
    /// colour the cloth when this is set.
    pub bli_regions_red: bool,
    /// Give the paths that get no region from Wicke's rules (BI, II, BLB and BLLB paths, cuts
    /// that do not separate, BLIs whose boundary partition and cone both fail) the region of
    /// the generalized winding number when their garment shows one
    /// ([`regions::RegionFinder::winding_region`]; ours), and colour it red (a BLI's only when
    /// `bli_regions_red` is set as well). Off in [`Options::default`]; on in Cha & Ko's loop.
    pub winding_regions: bool,
}

/// Runs the analysis of `mesh` at positions `pos` with default [`Options`].
pub fn analyze(mesh: &AnalysisMesh, pos: &[Vec3]) -> Result<Analysis, Inconsistency> {
    analyze_with(mesh, pos, &Options::default())
}

/// Runs the analysis of `mesh` at positions `pos`: inside rayon's pool
/// ([`crate::pool::in_pool`]), except for a small mesh (at most 512 triangles, swept by the
/// broad phase) analysed from a thread outside the pool, which runs on the calling thread with
/// at most one pool worker helping in the crossing pass (handing the whole analysis to the pool
/// and back costs two thread wake-ups, some 15 % of the exploded handkerchief's analysis with
/// two threads). The result is the same either way.
pub fn analyze_with(
    mesh: &AnalysisMesh,
    pos: &[Vec3],
    options: &Options,
) -> Result<Analysis, Inconsistency> {
    if rayon::current_thread_index().is_none() && mesh.triangles.len() <= HERE_MAX_TRIANGLES {
        let t0 = Instant::now();
        let boxes = crossings::triangle_boxes(mesh, pos);
        return match crossings::BroadPhase::sweep(&boxes) {
            Some(sweep) => {
                analyze_from(mesh, pos, options, t0, crossings::BroadPhase::Sweep(sweep))
            }
            // Too many overlaps for the sweep: the hierarchy, in the pool (boxes built once).
            None => {
                let broad = crossings::BroadPhase::hierarchy(&boxes);
                crate::pool::in_pool(|| analyze_from(mesh, pos, options, t0, broad))
            }
        };
    }
    crate::pool::in_pool(|| {
        let t0 = Instant::now();
        let boxes = crossings::triangle_boxes(mesh, pos);
        let broad = crossings::BroadPhase::new(&boxes);
        analyze_from(mesh, pos, options, t0, broad)
    })
}

/// Meshes with at most this many triangles (and a swept broad phase) are analysed on the
/// calling thread when it is outside rayon's pool. The two hand-overs it saves are a fixed
/// cost (some 30-60 us on the 2-CPU benchmark host): the exploded handkerchief (392 triangles,
/// 0.45-0.55 ms) gained 15 %, while at 800 triangles (about 2 ms) the in-pool crossing pass
/// (listing, then the kernel in stolen shares) measured 2-3 % faster than the caller/helper
/// claims (BENCHMARKS.md, an8).
const HERE_MAX_TRIANGLES: usize = 512;

/// [`analyze_with`]'s body after the broad phase (started at `t0`).
fn analyze_from(
    mesh: &AnalysisMesh,
    pos: &[Vec3],
    options: &Options,
    t0: Instant,
    broad: crossings::BroadPhase,
) -> Result<Analysis, Inconsistency> {
    let t1 = Instant::now();
    let crossings = crossings::find_crossings(mesh, pos, &broad);
    let t2 = Instant::now();
    let segs = segments::build_segments(mesh, &crossings)?;
    let (paths, tanglements) = paths::trace_paths(mesh, &crossings, &segs)?;
    let t3 = Instant::now();
    let mut finder = regions::RegionFinder::new(mesh);
    let mut red_vertex = vec![false; mesh.num_vertices()];
    let mut regions = Vec::with_capacity(paths.len());
    let mut winding_region_paths = Vec::new();
    for (i, p) in paths.iter().enumerate() {
        if mesh.objects[p.object as usize].kind != ObjectKind::Cloth {
            regions.push(Region::None);
            continue;
        }
        let bli = p.kind == PathKind::BoundaryLoopInside;
        let by_rule = if bli {
            match finder.bli_boundary_partition(p) {
                r @ Region::Inside(_) => r,
                _ => finder.bli_cone(p, &segs.segments, pos),
            }
        } else {
            finder.inside(p)
        };
        let r = match by_rule {
            Region::NotSeparating | Region::None if options.winding_regions => {
                let r = finder.winding_region(p, &segs.segments, pos);
                if let Region::Inside(_) = r {
                    winding_region_paths.push(i as u32);
                }
                r
            }
            r => r,
        };
        if let (Region::Inside(vs), true) = (&r, !bli || options.bli_regions_red) {
            for &v in vs {
                red_vertex[v as usize] = true;
            }
        }
        regions.push(r);
    }
    let coloring = coloring::color(mesh, red_vertex, &crossings, &segs.segments);
    let t4 = Instant::now();
    let ms = |a: Instant, b: Instant| (b - a).as_secs_f64() * 1e3;
    Ok(Analysis {
        crossings,
        segments: segs.segments,
        segments_of_crossing: segs.of_crossing,
        paths,
        tanglements,
        regions,
        winding_region_paths,
        coloring,
        timing: Timing {
            broad_phase: ms(t0, t1),
            crossings: ms(t1, t2),
            paths: ms(t2, t3),
            regions: ms(t3, t4),
            total: ms(t0, t4),
        },
    })
}
