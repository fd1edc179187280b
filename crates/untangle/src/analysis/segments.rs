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

/// Groups the crossings by triangle pair into segments. Linear after a sort of `2 x crossings`.
pub fn build_segments(
    mesh: &AnalysisMesh,
    crossings: &[Crossing],
) -> Result<Segments, Inconsistency> {
    let topo = &mesh.topology;
    let mut keyed: Vec<(u64, u32)> = Vec::with_capacity(crossings.len() * 2);
    for (ci, c) in crossings.iter().enumerate() {
        for &te in &topo.edge_triangles[c.edge as usize] {
            if te == NONE {
                continue;
            }
            let (lo, hi) = (te.min(c.triangle), te.max(c.triangle));
            keyed.push((((lo as u64) << 32) | hi as u64, ci as u32));
        }
    }
    // Stable: equal pairs keep crossing order.
    crate::radix::sort_by_bucket_then_key(
        &mut keyed,
        (mesh.triangles.len(), mesh.triangles.len()),
        |k| (k.0 >> 32) as u32,
        |k| k.0 as u32,
    );
    let mut segments = Vec::with_capacity(keyed.len() / 2 + 1);
    let mut of_crossing = vec![[NONE; 2]; crossings.len()];
    let mut i = 0;
    while i < keyed.len() {
        let key = keyed[i].0;
        let mut j = i;
        while j < keyed.len() && keyed[j].0 == key {
            j += 1;
        }
        let (ta, tb) = ((key >> 32) as u32, key as u32);
        let ends = match j - i {
            2 => [End::Crossing(keyed[i].1), End::Crossing(keyed[i + 1].1)],
            1 => {
                let (a, b) = (mesh.triangles[ta as usize], mesh.triangles[tb as usize]);
                let shared: Vec<u32> = a.iter().copied().filter(|v| b.contains(v)).collect();
                if shared.len() != 1 {
                    return Err(Inconsistency(
                        ta,
                        tb,
                        format!("one crossing but {} shared vertices", shared.len()),
                    ));
                }
                [End::Crossing(keyed[i].1), End::LoopVertex(shared[0])]
            }
            n => return Err(Inconsistency(ta, tb, format!("{n} crossings"))),
        };
        let s = segments.len() as u32;
        for k in i..j {
            let slot = &mut of_crossing[keyed[k].1 as usize];
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
