//! Intersection segments: each intersecting triangle pair contributes one segment with two
//! *pieces*, one in the parameter space of each triangle (Wicke et al. 2006, Sec. 4). A segment
//! ends at two crossings, or at one crossing and the vertex the two triangles share (a *loop
//! vertex*).

use super::crossings::Crossing;
use super::input::AnalysisMesh;
use crate::mesh::topology::NONE;

/// One end of a segment.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum End {
    /// A crossing (index into the crossing list).
    Crossing(u32),
    /// The vertex shared by the two triangles (a loop vertex).
    LoopVertex(u32),
}

/// The intersection of two triangles.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Segment {
    /// The two triangles, lower index first.
    pub triangles: [u32; 2],
    /// The two ends.
    pub ends: [End; 2],
}

/// Segments and, for each crossing, the (one or two) segments ending at it.
#[derive(Clone, Debug, Default)]
pub struct Segments {
    /// Segments sorted by triangle pair.
    pub segments: Vec<Segment>,
    /// For each crossing, the segments that end at it; the second is [`NONE`] when the crossing
    /// edge is a boundary edge.
    pub of_crossing: Vec<[u32; 2]>,
}

/// An inconsistency in the crossing structure. It cannot happen with the symbolically perturbed
/// predicates; it is reported rather than hidden, should it ever.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("inconsistent intersection structure at triangles {0} and {1}: {2}")]
pub struct Inconsistency(pub u32, pub u32, pub String);

/// Groups the crossings by triangle pair into segments. Linear: the `2 x crossings` entries
/// (triangle pair, crossing) are put in pair order by two counting sorts over the triangles
/// (by the higher triangle, then stably by the lower), or by a radix sort when the triangles far
/// outnumber the entries.
pub fn build_segments(
    mesh: &AnalysisMesh,
    crossings: &[Crossing],
) -> Result<Segments, Inconsistency> {
    let sorted = entries_by_pair(mesh, crossings);
    let n = sorted.len();
    let same_pair = |i: usize, lo: u32, hi: u32| i < n && sorted[i][0] == lo && sorted[i][1] == hi;
    // A segment takes one entry (loop vertex) or two: at most `n` segments, no regrowth.
    let mut segments = Vec::with_capacity(n);
    let mut of_crossing = vec![[NONE; 2]; crossings.len()];
    let mut i = 0;
    while i < n {
        let [ta, tb, c0] = sorted[i];
        let ends = if same_pair(i + 1, ta, tb) {
            if same_pair(i + 2, ta, tb) {
                let count = (i..n).take_while(|&k| same_pair(k, ta, tb)).count();
                return Err(Inconsistency(ta, tb, format!("{count} crossings")));
            }
            [End::Crossing(c0), End::Crossing(sorted[i + 1][2])]
        } else {
            let (a, b) = (mesh.triangles[ta as usize], mesh.triangles[tb as usize]);
            let mut shared = a.iter().copied().filter(|v| b.contains(v));
            match (shared.next(), shared.next()) {
                (Some(v), None) => [End::Crossing(c0), End::LoopVertex(v)],
                _ => {
                    let count = a.iter().filter(|v| b.contains(v)).count();
                    return Err(Inconsistency(
                        ta,
                        tb,
                        format!("one crossing but {count} shared vertices"),
                    ));
                }
            }
        };
        let s = segments.len() as u32;
        let j = if matches!(ends[1], End::Crossing(_)) {
            i + 2
        } else {
            i + 1
        };
        for entry in &sorted[i..j] {
            let slot = &mut of_crossing[entry[2] as usize];
            if slot[0] == NONE {
                slot[0] = s;
            } else {
                slot[1] = s;
            }
        }
        segments.push(Segment {
            triangles: [ta, tb],
            ends,
        });
        i = j;
    }
    Ok(Segments {
        segments,
        of_crossing,
    })
}

/// Calls `f(lo, hi, crossing)` for each triangle pair `lo < hi` a crossing belongs to (the
/// crossed triangle with each triangle beside the crossing edge), in crossing order.
#[inline(always)]
fn for_each_entry(mesh: &AnalysisMesh, crossings: &[Crossing], mut f: impl FnMut(u32, u32, u32)) {
    let edge_triangles = &mesh.topology.edge_triangles;
    for (ci, c) in crossings.iter().enumerate() {
        for &te in &edge_triangles[c.edge as usize] {
            if te != NONE {
                f(te.min(c.triangle), te.max(c.triangle), ci as u32);
            }
        }
    }
}

/// Every entry `[lo, hi, crossing]` of [`for_each_entry`], sorted by `(lo, hi)`; equal pairs
/// keep crossing order.
fn entries_by_pair(mesh: &AnalysisMesh, crossings: &[Crossing]) -> Vec<[u32; 3]> {
    let nt = mesh.triangles.len();
    // Counting sort by the higher triangle: its histogram, and the number of entries.
    let mut start = vec![0u32; nt + 1];
    for_each_entry(mesh, crossings, |_, hi, _| start[hi as usize + 1] += 1);
    let n = start.iter().sum::<u32>() as usize;
    if 2 * nt > 8 * n {
        // Few entries among many triangles: the histograms would dominate.
        let mut v = Vec::with_capacity(n);
        for_each_entry(mesh, crossings, |lo, hi, c| v.push([lo, hi, c]));
        crate::radix::sort_by_key(&mut v, |x| ((x[0] as u64) << 32) | x[1] as u64);
        return v;
    }
    for h in 1..=nt {
        start[h] += start[h - 1];
    }
    let mut lo_start = vec![0u32; nt + 1];
    // SAFETY: the entries are the same as in the histogram pass above (same crossings, same
    // order), so bucket `hi` receives exactly its count at the consecutive positions from its
    // start: every position of `0..n` is written once.
    let by_hi: Vec<[u32; 2]> = unsafe {
        crate::radix::written_once(n, |by_hi| {
            for_each_entry(mesh, crossings, |lo, hi, c| {
                let s = &mut start[hi as usize];
                by_hi[*s as usize].write([lo, c]);
                *s += 1;
                lo_start[lo as usize + 1] += 1;
            })
        })
    };
    for t in 1..=nt {
        lo_start[t] += lo_start[t - 1];
    }
    // Stable counting sort by the lower triangle; `start[h]` is now the end of bucket `h`.
    // SAFETY: `lo_start` holds the bucket starts of the histogram of the lower triangles of
    // all `n` entries of `by_hi`, each visited once: every position of `0..n` is written once.
    unsafe {
        crate::radix::written_once(n, |out| {
            let mut begin = 0;
            for (hi, &end) in start[..nt].iter().enumerate() {
                for &[lo, c] in &by_hi[begin as usize..end as usize] {
                    let s = &mut lo_start[lo as usize];
                    out[*s as usize].write([lo, hi as u32, c]);
                    *s += 1;
                }
                begin = end;
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::ObjectKind;
    use crate::geom::Vec3;
    use proptest::prelude::*;

    proptest! {
        /// The counting sorts (many crossings) and the radix fallback (few) put the entries in
        /// the order of a stable comparison sort by triangle pair.
        #[test]
        fn entries_are_in_stable_pair_order(
            picks in proptest::collection::vec((0usize..1000, 0usize..1000), 0..400),
            n in 2usize..9,
        ) {
            let sheet = crate::scenes::sheet::handkerchief("s", n, n, 1.0, 1.0, |p| {
                Vec3::new(p.x, p.y, 0.0)
            });
            let (mesh, _) = AnalysisMesh::new(&[(&sheet, ObjectKind::Cloth)]).expect("valid");
            let topo = &mesh.topology;
            // Crossings of edges through triangles not incident to them, sorted and distinct.
            let mut crossings: Vec<Crossing> = picks
                .iter()
                .map(|&(e, t)| Crossing {
                    edge: (e % topo.edge_triangles.len()) as u32,
                    triangle: (t % mesh.triangles.len()) as u32,
                })
                .filter(|c| !topo.edge_triangles[c.edge as usize].contains(&c.triangle))
                .collect();
            crossings.sort_unstable();
            crossings.dedup();
            let mut brute = Vec::new();
            for_each_entry(&mesh, &crossings, |lo, hi, c| brute.push([lo, hi, c]));
            brute.sort_by_key(|x| (x[0], x[1])); // stable
            prop_assert_eq!(entries_by_pair(&mesh, &crossings), brute);
        }
    }
}
