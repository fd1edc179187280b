//! Regionless tanglements **(ours, beyond the paper)**: a fallback colouring for a loop that has
//! stalled with intersections but no red vertex.
//!
//! Cha & Ko's operations need red vertices (Sec. 3: the smaller side of each partitioning path)
//! or red* triangles (Sec. 5.1.2). Some tanglements have neither a usable region nor a red*
//! shrink that can finish:
//!
//! a partitioning path (CLOSED, LL, BB) whose cut is empty, e.g. a fold pinched through itself,
//! where the path runs out along some triangles and back through the same ones, so every edge
//! is crossed an even number of times (the CROSS case after ~60 steps, see `docs/cha-ko.md`).
//! Their only red* triangles then often have a loop vertex as the shrink target, and a shrink
//! toward a corner of the crossed triangle itself is a homothety that cannot end the crossing;
//! the crossing edges and triangles are red, but their green corners keep them locked in place
//! (red-green pairs are held apart by `eps_RG`, Sec. 5.3).
//!
//! The fallback colours red every corner of every intersecting triangle of such a tanglement
//! (both triangles of every segment of its paths), except loop vertices (they belong to both
//! sides of their curve), and recolours edges, triangles, out-most red vertices and red*
//! triangles by the rules of Sec. 3. The pairs around the intersection curve may then cross
//! (red-red), and the out-most of the new red vertices are pulled toward their green
//! neighbours: the cloth around the curve contracts in uv, which shortens the curve. The loop
//! ([`super::Resolver`]) applies it, when enabled (`ResolveParams::regionless_after`, off by
//! default), only after that many steps without a new lowest count of intersecting pairs while
//! no vertex is red; each use is recorded in the step report. It is off by default because it
//! is a gamble: at N = 30 it turns 0 / 7 resolved CROSS runs into 6 / 7, but on `cross` it
//! helps only for N = 25-40, and on the exploded handkerchief it fires in long stalls that the
//! paper's operations would have ended and made 2 of 12 seeds stuck (docs/cha-ko.md).

use crate::analysis::{coloring, Analysis, AnalysisMesh, Region};

/// Whether path `i` of `analysis` is regionless in the sense of the module documentation: a
/// partitioning path (CLOSED, LL, BB) without a non-empty inside region.
pub fn is_regionless(analysis: &Analysis, i: usize) -> bool {
    let p = &analysis.paths[i];
    p.kind.is_partitioning()
        && match &analysis.regions[i] {
            Region::Inside(vs) => vs.is_empty(),
            Region::None => true,
            Region::NotSeparating => false,
        }
}

/// The red vertices after the fallback: the analysis' red vertices plus every corner of every
/// intersecting triangle of each tanglement with a regionless path, except loop vertices (of
/// any path: a loop vertex lies on both sides of its curve). `None` when no tanglement has a regionless path.
pub fn regionless_red(mesh: &AnalysisMesh, analysis: &Analysis) -> Option<Vec<bool>> {
    let mut red = analysis.coloring.red_vertex.clone();
    let loops = analysis.loop_vertices();
    let mut any = false;
    for t in &analysis.tanglements {
        if !t.paths.iter().any(|&i| is_regionless(analysis, i as usize)) {
            continue;
        }
        any = true;
        for &i in &t.paths {
            for &piece in analysis.paths[i as usize].pieces() {
                for &tri in &analysis.segments[(piece / 2) as usize].triangles {
                    for &v in &mesh.triangles[tri as usize] {
                        if loops.binary_search(&v).is_err() {
                            red[v as usize] = true;
                        }
                    }
                }
            }
        }
    }
    any.then_some(red)
}

/// Applies the fallback to `analysis` (recolouring it by Sec. 3 from the new red vertices).
/// Returns how many vertices turned red (0 when no tanglement is regionless).
pub fn color_regionless(mesh: &AnalysisMesh, analysis: &mut Analysis) -> usize {
    let Some(red) = regionless_red(mesh, analysis) else {
        return 0;
    };
    let before = analysis.coloring.num_red_vertices();
    analysis.coloring = coloring::color(mesh, red, &analysis.crossings, &analysis.segments);
    analysis.coloring.num_red_vertices() - before
}
