//! Intersection paths in parameter space, their correspondence and classification (Wicke et al.
//! 2006, Sec. 4 and 4.1).
//!
//! Pieces (one per segment and triangle) are linked, not segments: at a crossing of an edge of
//! the piece's own triangle the path passes across that edge into the neighbouring triangle; at a
//! crossing of the other triangle's edge the path stays in its triangle and continues with the
//! segment against the other triangle's neighbour; at a loop vertex it turns back into the other
//! piece of its own segment. A boundary edge ends the path: `B` on the edge's side, `I` on the
//! other. Every piece has two links, so the pieces form chains and cycles, found in one linear
//! sweep (Wicke's path assembly was quadratic).
//!
//! Kinds: a closed chain is CLOSED (no turn), EIGHT (two turns at one vertex) or LL (turns at two
//! vertices); an open chain with one turn is BLI (BLB if both ends are on a boundary); an open
//! chain without turn is BB, BI or II. Two BLI chains sharing their loop vertex form a CROSS. As
//! the paper says, EIGHT is split at the loop vertex into two corresponding CLOSED paths and CROSS
//! into a BB/II pair; the original kind is kept as the tanglement kind.
//!
//! Under the symbolic perturbation a boundary crossing always gives one `B` and one `I` end, so
//! BLB, BLLB and BB/BI pairs cannot occur; they are listed for completeness.

use super::crossings::Crossing;
use super::input::AnalysisMesh;
use super::segments::{End, Inconsistency, Segments};
use crate::mesh::topology::NONE;
use std::sync::atomic::{AtomicU32, Ordering::Relaxed};

/// Kind of a parameter-space path (Wicke et al. 2006, Sec. 4.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
pub enum PathKind {
    /// Closed, no loop vertex.
    #[serde(rename = "CLOSED")]
    Closed,
    /// Closed, one loop vertex met twice (split into two CLOSED paths).
    #[serde(rename = "EIGHT")]
    Eight,
    /// Closed, two loop vertices.
    #[serde(rename = "LL")]
    LoopLoop,
    /// Open, one loop vertex, one end on the boundary and one inside.
    #[serde(rename = "BLI")]
    BoundaryLoopInside,
    /// Open, one loop vertex, both ends on the boundary.
    #[serde(rename = "BLB")]
    BoundaryLoopBoundary,
    /// Open, two loop vertices.
    #[serde(rename = "BLLB")]
    BoundaryLoopLoopBoundary,
    /// Two BLI paths sharing their loop vertex (split into a BB/II pair).
    #[serde(rename = "CROSS")]
    Cross,
    /// Open, no loop vertex, both ends on the boundary.
    #[serde(rename = "BB")]
    BoundaryBoundary,
    /// Open, no loop vertex, one end on the boundary.
    #[serde(rename = "BI")]
    BoundaryInside,
    /// Open, no loop vertex, both ends inside.
    #[serde(rename = "II")]
    InsideInside,
}

impl PathKind {
    /// The paper's name.
    pub fn name(self) -> &'static str {
        match self {
            PathKind::Closed => "CLOSED",
            PathKind::Eight => "EIGHT",
            PathKind::LoopLoop => "LL",
            PathKind::BoundaryLoopInside => "BLI",
            PathKind::BoundaryLoopBoundary => "BLB",
            PathKind::BoundaryLoopLoopBoundary => "BLLB",
            PathKind::Cross => "CROSS",
            PathKind::BoundaryBoundary => "BB",
            PathKind::BoundaryInside => "BI",
            PathKind::InsideInside => "II",
        }
    }

    /// Whether a path of this kind partitions the mesh (CLOSED, LL, BB; Wicke Sec. 4.2).
    pub fn is_partitioning(self) -> bool {
        matches!(
            self,
            PathKind::Closed | PathKind::LoopLoop | PathKind::BoundaryBoundary
        )
    }
}

/// How an open path ends.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum EndKind {
    /// On a boundary edge of its own mesh.
    #[serde(rename = "B")]
    Boundary,
    /// Inside its mesh (where a boundary edge of the other sheet pierces it).
    #[serde(rename = "I")]
    Inside,
}

/// Link target of a piece end where its path ends on a boundary edge of its own mesh (`B`).
const END_B: u32 = u32::MAX;
/// Link target of a piece end where its path ends inside its mesh (`I`).
const END_I: u32 = u32::MAX - 1;

/// The end kind of a terminal link target.
#[inline]
fn end_kind(link: u32) -> EndKind {
    if link == END_B {
        EndKind::Boundary
    } else {
        EndKind::Inside
    }
}

/// Piece `2 s + side` is segment `s` in the parameter space of `segments[s].triangles[side]`.
#[inline]
pub fn piece_triangle(segs: &Segments, piece: u32) -> u32 {
    segs.segments[(piece / 2) as usize].triangles[(piece % 2) as usize]
}

/// The corresponding piece (same segment, other triangle).
#[inline]
pub fn partner(piece: u32) -> u32 {
    piece ^ 1
}

/// A parameter-space intersection path.
///
/// Its three index lists (pieces, cut edges, loop vertices) share one allocation (an analysis
/// of a dense tangle has thousands of paths; one heap block each instead of three); read them
/// with [`Path::pieces`], [`Path::cut_edges`] and [`Path::loop_vertices`].
#[derive(Clone, PartialEq)]
pub struct Path {
    /// Kind after splitting (never EIGHT or CROSS).
    pub kind: PathKind,
    /// EIGHT or CROSS when this path came from splitting one.
    pub split_from: Option<PathKind>,
    /// Whether the path is closed.
    pub closed: bool,
    /// End kinds of an open path (first piece's end, last piece's end).
    pub ends: Option<[EndKind; 2]>,
    /// Index of the corresponding path (itself for LL and BLI).
    pub corresponds_to: u32,
    /// Index of the tanglement this path belongs to.
    pub tanglement: u32,
    /// Object whose parameter space holds the path.
    pub object: u32,
    /// The pieces, then the cut edges, then the loop vertices.
    lists: Vec<u32>,
    /// Where the cut edges and the loop vertices start in `lists`.
    starts: [u32; 2],
}

impl Path {
    /// A path with the given lists (`cut_edges` ascending, `loop_vertices` ascending and
    /// distinct); `corresponds_to` and `tanglement` are set later.
    fn new(
        (kind, split_from): (PathKind, Option<PathKind>),
        (closed, ends): (bool, Option<[EndKind; 2]>),
        pieces: impl ExactSizeIterator<Item = u32>,
        cut_edges: &[u32],
        loop_vertices: &[u32],
        object: u32,
    ) -> Path {
        let mut lists = Vec::with_capacity(pieces.len() + cut_edges.len() + loop_vertices.len());
        lists.extend(pieces);
        let cut_start = lists.len() as u32;
        lists.extend_from_slice(cut_edges);
        let loop_start = lists.len() as u32;
        lists.extend_from_slice(loop_vertices);
        Path {
            kind,
            split_from,
            closed,
            ends,
            corresponds_to: u32::MAX,
            tanglement: u32::MAX,
            object,
            lists,
            starts: [cut_start, loop_start],
        }
    }

    /// Pieces in order along the path.
    #[inline]
    pub fn pieces(&self) -> &[u32] {
        &self.lists[..self.starts[0] as usize]
    }

    /// Edges the path passes across an odd number of times (the cut of a partitioning path),
    /// ascending.
    #[inline]
    pub fn cut_edges(&self) -> &[u32] {
        &self.lists[self.starts[0] as usize..self.starts[1] as usize]
    }

    /// Distinct loop vertices on the path, ascending.
    #[inline]
    pub fn loop_vertices(&self) -> &[u32] {
        &self.lists[self.starts[1] as usize..]
    }
}

/// The fields in declaration order of the public view (as a derived `Debug` of a struct with
/// `pieces`, `loop_vertices` and `cut_edges` fields would print them).
impl std::fmt::Debug for Path {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Path")
            .field("kind", &self.kind)
            .field("split_from", &self.split_from)
            .field("pieces", &self.pieces())
            .field("closed", &self.closed)
            .field("ends", &self.ends)
            .field("loop_vertices", &self.loop_vertices())
            .field("corresponds_to", &self.corresponds_to)
            .field("tanglement", &self.tanglement)
            .field("object", &self.object)
            .field("cut_edges", &self.cut_edges())
            .finish()
    }
}

/// The one or two paths of a tanglement, stored inline (no heap block per tanglement); a slice
/// by [`std::ops::Deref`].
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct TanglementPaths {
    ids: [u32; 2],
    len: u8,
}

impl TanglementPaths {
    /// One path.
    pub fn one(a: u32) -> Self {
        TanglementPaths {
            ids: [a, u32::MAX],
            len: 1,
        }
    }

    /// Two corresponding paths.
    pub fn two(a: u32, b: u32) -> Self {
        TanglementPaths {
            ids: [a, b],
            len: 2,
        }
    }
}

impl std::ops::Deref for TanglementPaths {
    type Target = [u32];
    #[inline]
    fn deref(&self) -> &[u32] {
        &self.ids[..self.len as usize]
    }
}

impl<'a> IntoIterator for &'a TanglementPaths {
    type Item = &'a u32;
    type IntoIter = std::slice::Iter<'a, u32>;
    fn into_iter(self) -> Self::IntoIter {
        self.iter()
    }
}

/// As a list (like the slice it derefs to).
impl std::fmt::Debug for TanglementPaths {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.iter()).finish()
    }
}

/// A tanglement: one intersection curve in world space with its parameter-space paths; its kind
/// is one of Cha & Ko's seven categories (CLOSED, EIGHT, LL, BLI, CROSS, BBII, BIBI).
#[derive(Clone, Debug, PartialEq)]
pub struct Tanglement {
    /// Category, e.g. `"BBII"`.
    pub kind: &'static str,
    /// Its paths.
    pub paths: TanglementPaths,
    /// The objects involved (the same object twice for a self-intersection).
    pub objects: [u32; 2],
    /// Loop vertices involved.
    pub loop_vertices: Vec<u32>,
}

/// A chain of pieces found by the linking sweep, before classification.
struct Chain {
    /// Range of its `(piece, entry end)` steps, in walking order, in the shared step list.
    steps: std::ops::Range<usize>,
    closed: bool,
    ends: Option<[EndKind; 2]>,
    /// Positions `i` where step `i + 1` is the partner of step `i` (a turn at a loop vertex),
    /// with the vertex; for a closed chain the wrap-around is position `len - 1`.
    turns: Vec<(usize, u32)>,
}

/// Links every piece end: `links[piece][k]` is `2 * next + entry`, where the path leaving
/// `piece` through its end `k` continues into piece `next` entering at its end `entry`, or
/// [`END_B`] / [`END_I`] where the path ends. Also returns, per piece end, the edge of the
/// piece's own triangle the path passes across there ([`NONE`] if none).
///
/// Built crossing by crossing: a crossing of edge `e` (triangles `x`, `y`) through triangle `t`
/// ends the segments `{x, t}` and `{y, t}`; their pieces in `x` and `y` continue into each other
/// across `e`, and their pieces in `t` continue into each other inside `t`. On a boundary edge
/// (no `y`) the piece in `x` ends with `B` and the piece in `t` with `I`. Piece indices must stay
/// below `2^31 - 2` (the links pack the entry end into the low bit; the three largest values
/// are [`END_B`], [`END_I`] and `WALKED`).
#[allow(clippy::type_complexity)]
fn link_pieces(
    mesh: &AnalysisMesh,
    crossings: &[Crossing],
    segs: &Segments,
) -> Result<(Vec<[u32; 2]>, Vec<[u32; 2]>), Inconsistency> {
    let segments = &segs.segments;
    let n = segments.len() * 2;
    let mut links = vec![[END_I; 2]; n];
    let mut across = vec![[NONE; 2]; n];
    // At a loop vertex the path turns back into the other piece of its segment.
    for (s, seg) in segments.iter().enumerate() {
        for (k, end) in seg.ends.iter().enumerate() {
            if let End::LoopVertex(_) = end {
                let p = 2 * s;
                links[p][k] = 2 * (p as u32 + 1) + k as u32;
                links[p + 1][k] = 2 * p as u32 + k as u32;
            }
        }
    }
    // Each piece end is written by the one crossing at that end (a segment's two ends are
    // distinct crossings or a loop vertex), so the crossings can be linked in any order, or
    // in two halves side by side: the links are the same.
    {
        let (links_view, across_view) = (atomic_view(&mut links), atomic_view(&mut across));
        let link = |range: std::ops::Range<usize>| {
            link_crossings(mesh, crossings, segs, range, links_view, across_view)
        };
        let nc = crossings.len();
        if nc >= PAR_LINK_CROSSINGS && rayon::current_num_threads() > 1 {
            // The first inconsistency in crossing order, as the sequential loop reports it.
            let (first, second) = rayon::join(|| link(0..nc / 2), || link(nc / 2..nc));
            first?;
            second?;
        } else {
            link(0..nc)?;
        }
    }
    Ok((links, across))
}

/// Crossings from which [`link_pieces`] links the two halves of the crossing list side by side
/// (below it, waking the second thread costs more than it saves: on the exploded handkerchief,
/// 4,249 pairs, the paths phase took 0.38-0.48 ms split against 0.32-0.35 ms in one piece).
const PAR_LINK_CROSSINGS: usize = 1 << 16;

/// `v` as atomics (same size and bit validity), so that disjoint entries can be written from
/// two threads through shared references.
fn atomic_view(v: &mut [[u32; 2]]) -> &[[AtomicU32; 2]] {
    // SAFETY: `[AtomicU32; 2]` has the size, alignment and bit validity of `[u32; 2]`, and the
    // exclusive borrow of `v` lasts as long as the view, so nothing else reads or writes it
    // meanwhile.
    unsafe { &*(v as *mut [[u32; 2]] as *const [[AtomicU32; 2]]) }
}

/// The links and edges passed across at the crossings `range` of [`link_pieces`]: the piece
/// ends of the segments ending at each crossing, written with relaxed stores (each end by its
/// own crossing only). Returns the first inconsistency in the range.
fn link_crossings(
    mesh: &AnalysisMesh,
    crossings: &[Crossing],
    segs: &Segments,
    range: std::ops::Range<usize>,
    links: &[[AtomicU32; 2]],
    across: &[[AtomicU32; 2]],
) -> Result<(), Inconsistency> {
    let topo = &mesh.topology;
    let segments = &segs.segments;
    let set = |v: &[[AtomicU32; 2]], p: usize, k: usize, x: u32| v[p][k].store(x, Relaxed);
    // The end of segment `s` at crossing `c` and the side of `s` in triangle `t`.
    let place = |s: u32, c: u32, t: u32| -> Option<(usize, usize)> {
        let seg = segments.get(s as usize)?;
        let k = seg.ends.iter().position(|e| *e == End::Crossing(c))?;
        let side = seg.triangles.iter().position(|&x| x == t)?;
        Some((k, side))
    };
    for (c, cr) in range.clone().zip(&crossings[range]) {
        let c = c as u32;
        let [sa, sb] = segs.of_crossing[c as usize];
        let t = cr.triangle;
        let unexpected = |s: u32| {
            let tri = segments.get(s as usize).map_or(t, |g| g.triangles[0]);
            Inconsistency(
                tri,
                t,
                "crossing continues into an unexpected segment".into(),
            )
        };
        let (ka, side_a) = place(sa, c, t).ok_or_else(|| unexpected(sa))?;
        let pa_t = 2 * sa as usize + side_a;
        let pa_e = pa_t ^ 1;
        let x = segments[sa as usize].triangles[1 - side_a];
        let y = topo.other_triangle(cr.edge, x);
        set(across, pa_e, ka, cr.edge);
        if y == NONE {
            set(links, pa_e, ka, END_B);
            set(links, pa_t, ka, END_I);
            continue;
        }
        if sb == NONE {
            return Err(Inconsistency(
                x,
                t,
                "crossing with one segment on an interior edge".into(),
            ));
        }
        let (kb, side_b) = place(sb, c, t).ok_or_else(|| unexpected(sb))?;
        if segments[sb as usize].triangles[1 - side_b] != y {
            return Err(unexpected(sb));
        }
        let pb_t = 2 * sb as usize + side_b;
        let pb_e = pb_t ^ 1;
        set(across, pb_e, kb, cr.edge);
        let to = |p: usize, k: usize| (2 * p + k) as u32;
        set(links, pa_e, ka, to(pb_e, kb));
        set(links, pb_e, kb, to(pa_e, ka));
        set(links, pa_t, ka, to(pb_t, kb));
        set(links, pb_t, kb, to(pa_t, ka));
    }
    Ok(())
}

/// Marks a piece as walked in [`walk_chains`] (both of its links are overwritten with it; it
/// differs from every piece link and from [`END_B`] / [`END_I`]).
const WALKED: u32 = u32::MAX - 2;

/// The chains and cycles of linked pieces, with all their steps in one list. Consumes `links`:
/// a walked piece's links are overwritten with [`WALKED`] (no separate visited flags; the test
/// reads the links that the walk reads next anyway).
fn walk_chains(links: &mut [[u32; 2]], segs: &Segments) -> (Vec<Chain>, Vec<(u32, u8)>) {
    let n = links.len();
    let mut all_steps: Vec<(u32, u8)> = Vec::with_capacity(n);
    let mut chains = Vec::new();
    let loop_vertex_of = |piece: u32| -> u32 {
        let seg = &segs.segments[(piece / 2) as usize];
        seg.ends
            .iter()
            .find_map(|e| match e {
                End::LoopVertex(v) => Some(*v),
                _ => None,
            })
            .unwrap_or(NONE)
    };
    // Follows the chain from `start` entered at `entry`, until a terminal or back at `start`.
    let walk = |start: u32, entry: u8, links: &mut [[u32; 2]], all: &mut Vec<(u32, u8)>| {
        let first = all.len();
        let mut turns = Vec::new();
        let (mut p, mut e) = (start, entry);
        loop {
            let link = links[p as usize][1 - e as usize];
            links[p as usize] = [WALKED; 2];
            all.push((p, e));
            if link >= END_I {
                return Chain {
                    steps: first..all.len(),
                    closed: false,
                    ends: Some([EndKind::Inside, end_kind(link)]),
                    turns,
                };
            }
            let (piece, end) = (link >> 1, (link & 1) as u8);
            if piece == partner(p) {
                turns.push((all.len() - 1 - first, loop_vertex_of(p)));
            }
            // Back at the start, or (cannot happen for consistent, mutual links) at a walked
            // piece: stop rather than loop.
            if (piece == start && end == entry) || links[piece as usize][0] == WALKED {
                return Chain {
                    steps: first..all.len(),
                    closed: true,
                    ends: None,
                    turns,
                };
            }
            p = piece;
            e = end;
        }
    };
    for p in 0..n as u32 {
        for k in 0..2u8 {
            let link = links[p as usize][k as usize];
            if link == WALKED {
                break;
            }
            if link >= END_I {
                let mut ch = walk(p, k, links, &mut all_steps);
                if let Some(ends) = ch.ends.as_mut() {
                    ends[0] = end_kind(link);
                }
                chains.push(ch);
            }
        }
    }
    for p in 0..n as u32 {
        if links[p as usize][0] != WALKED {
            chains.push(walk(p, 0, links, &mut all_steps));
        }
    }
    (chains, all_steps)
}

/// Appends to `out` the edges crossed an odd number of times between the pieces of `steps`,
/// ascending; when the sub-path starts or ends with a `B` end, that boundary edge counts too. `across` is per piece end the
/// edge passed across there (from [`link_pieces`]).
fn cut_of(
    across: &[[u32; 2]],
    steps: &[(u32, u8)],
    (closed, b_start, b_end): (bool, bool, bool),
    odd: &mut OddEdges,
    out: &mut Vec<u32>,
) {
    let count = steps.len();
    let transitions = if closed {
        count
    } else {
        count.saturating_sub(1)
    };
    let mut push = |p: u32, exit: u8| {
        let e = across[p as usize][exit as usize];
        if e != NONE {
            odd.toggle(e);
        }
    };
    for &(p, e) in &steps[..transitions] {
        push(p, 1 - e);
    }
    if b_start {
        let (p, e) = steps[0];
        push(p, e);
    }
    if b_end {
        let (p, e) = steps[count - 1];
        push(p, 1 - e);
    }
    odd.take_into(out)
}

/// The edges seen an odd number of times, sorted, without sorting the sequence: a parity bit
/// per edge, read back word by word over the span of the edges seen when that span is short
/// (a path's edges are close in index), else from the list of edges seen, sorted.
struct OddEdges {
    /// Parity bit of each edge; all zero between uses.
    parity: Vec<u64>,
    /// Edges seen since the last [`OddEdges::take`], with repetitions.
    seen: Vec<u32>,
}

impl OddEdges {
    fn new(num_edges: usize) -> Self {
        OddEdges {
            parity: vec![0; num_edges / 64 + 1],
            seen: Vec::new(),
        }
    }

    #[inline]
    fn toggle(&mut self, e: u32) {
        self.parity[(e / 64) as usize] ^= 1 << (e % 64);
        self.seen.push(e);
    }

    /// The edges toggled an odd number of times since the last call, ascending.
    #[cfg(test)]
    fn take(&mut self) -> Vec<u32> {
        let mut out = Vec::new();
        self.take_into(&mut out);
        out
    }

    /// Appends the edges toggled an odd number of times since the last call to `out`,
    /// ascending; clears.
    fn take_into(&mut self, out: &mut Vec<u32>) {
        let (Some(&lo), Some(&hi)) = (self.seen.iter().min(), self.seen.iter().max()) else {
            return;
        };
        let (w0, w1) = ((lo / 64) as usize, (hi / 64) as usize);
        let first = out.len();
        out.reserve(self.seen.len());
        if w1 - w0 < 4 * self.seen.len() + 8 {
            for (w, word) in self.parity[w0..=w1].iter_mut().enumerate() {
                let mut x = std::mem::take(word);
                while x != 0 {
                    out.push(((w0 + w) * 64) as u32 + x.trailing_zeros());
                    x &= x - 1;
                }
            }
        } else {
            for &e in &self.seen {
                let word = &mut self.parity[(e / 64) as usize];
                let bit = 1u64 << (e % 64);
                if *word & bit != 0 {
                    *word &= !bit;
                    out.push(e);
                }
            }
            out[first..].sort_unstable();
        }
        self.seen.clear();
    }
}

/// Steps (pieces along the chains) from which [`trace_paths`] makes the paths of two halves of
/// the chains side by side. On the exploded ball of 800 triangles (28k steps, analysed inside
/// the pool) the split took the paths phase from 0.74 to 0.69-0.70 ms at two threads; at 4,096
/// it also split the 392-triangle handkerchief (8.5k steps, analysed from outside the pool,
/// where the join hands the work over), which then lost 10-15 % (BENCHMARKS.md, "Broad phase by
/// density"). Linking (below [`PAR_LINK_CROSSINGS`]) gained nothing from a split at these
/// sizes.
const PAR_PATH_STEPS: usize = 1 << 14;

/// Paths and tanglements of the given segments.
pub fn trace_paths(
    mesh: &AnalysisMesh,
    crossings: &[Crossing],
    segs: &Segments,
) -> Result<(Vec<Path>, Vec<Tanglement>), Inconsistency> {
    let (mut links, across) = link_pieces(mesh, crossings, segs)?;
    let (chains, all_steps) = walk_chains(&mut links, segs);
    let steps_of = |c: &Chain| &all_steps[c.steps.clone()];
    let object_of_piece = |p: u32| mesh.object_of_triangle[piece_triangle(segs, p) as usize];

    // Classify chains; BLI chains are grouped by loop vertex to find CROSS pairs.
    let mut bli_by_vertex: std::collections::BTreeMap<u32, Vec<usize>> = Default::default();
    #[derive(Clone, Copy, PartialEq)]
    enum Class {
        Plain(PathKind),
        Eight,
        Bli,
    }
    let mut classes = Vec::with_capacity(chains.len());
    for (ci, ch) in chains.iter().enumerate() {
        let class = if ch.closed {
            match ch.turns.len() {
                0 => Class::Plain(PathKind::Closed),
                2 if ch.turns[0].1 == ch.turns[1].1 => Class::Eight,
                _ => Class::Plain(PathKind::LoopLoop),
            }
        } else {
            let ends = ch.ends.expect("open chains have ends");
            match ch.turns.len() {
                0 => Class::Plain(match ends {
                    [EndKind::Boundary, EndKind::Boundary] => PathKind::BoundaryBoundary,
                    [EndKind::Inside, EndKind::Inside] => PathKind::InsideInside,
                    _ => PathKind::BoundaryInside,
                }),
                1 if ends == [EndKind::Boundary, EndKind::Boundary] => {
                    Class::Plain(PathKind::BoundaryLoopBoundary)
                }
                1 => {
                    bli_by_vertex.entry(ch.turns[0].1).or_default().push(ci);
                    Class::Bli
                }
                _ => Class::Plain(PathKind::BoundaryLoopLoopBoundary),
            }
        };
        classes.push(class);
    }
    // CROSS: exactly two BLI chains at one loop vertex.
    let mut cross_partner = vec![usize::MAX; chains.len()];
    for list in bli_by_vertex.values() {
        if list.len() == 2 {
            cross_partner[list[0]] = list[1];
            cross_partner[list[1]] = list[0];
        }
    }

    // The paths of the chains `range` in chain order, with the tanglement kind of each path
    // where the split decides it. Chains are independent here (a CROSS pair is made at its
    // first chain, reading the second), so ranges of chains can be made side by side and
    // concatenated.
    let paths_of_chains = |range: std::ops::Range<usize>| {
        let make_path = |paths: &mut Vec<Path>,
                         kinds: (PathKind, Option<PathKind>),
                         steps: &[(u32, u8)],
                         shape: (bool, Option<[EndKind; 2]>),
                         loop_vertices: &[u32],
                         cut_edges: &[u32]| {
            paths.push(Path::new(
                kinds,
                shape,
                steps.iter().map(|s| s.0),
                cut_edges,
                loop_vertices,
                object_of_piece(steps[0].0),
            ));
        };
        // One path per chain, two per EIGHT (a CROSS pair of chains gives at most two): reserved
        // once.
        let eights = classes[range.clone()]
            .iter()
            .filter(|&&c| c == Class::Eight)
            .count();
        let mut paths: Vec<Path> = Vec::with_capacity(range.len() + eights);
        let mut scratch = OddEdges::new(mesh.topology.num_edges());
        // Reused buffers for a path's cut edges and loop vertices (copied into the path).
        let mut cut: Vec<u32> = Vec::new();
        let mut lv: Vec<u32> = Vec::new();
        let mut wrapped: Vec<(u32, u8)> = Vec::new();

        let mut tanglement_kind_of_path: Vec<Option<&'static str>> =
            Vec::with_capacity(paths.capacity());
        for (ci, ch) in range.clone().zip(&chains[range]) {
            match classes[ci] {
                Class::Plain(kind) => {
                    let b0 = ch.ends.map(|e| e[0] == EndKind::Boundary).unwrap_or(false);
                    let b1 = ch.ends.map(|e| e[1] == EndKind::Boundary).unwrap_or(false);
                    cut.clear();
                    let flags = (ch.closed, b0, b1);
                    cut_of(&across, steps_of(ch), flags, &mut scratch, &mut cut);
                    lv.clear();
                    lv.extend(ch.turns.iter().map(|t| t.1));
                    lv.sort_unstable();
                    lv.dedup();
                    make_path(
                        &mut paths,
                        (kind, None),
                        steps_of(ch),
                        (ch.closed, ch.ends),
                        &lv,
                        &cut,
                    );
                    tanglement_kind_of_path.push(None);
                }
                Class::Eight => {
                    let (i, j) = (ch.turns[0].0, ch.turns[1].0);
                    let v = ch.turns[0].1;
                    let steps = steps_of(ch);
                    // The first lobe is a run of the chain; the second wraps around its start.
                    wrapped.clear();
                    wrapped.extend_from_slice(&steps[j + 1..]);
                    wrapped.extend_from_slice(&steps[..=i]);
                    for lobe in [&steps[i + 1..=j], &wrapped[..]] {
                        cut.clear();
                        cut_of(&across, lobe, (true, false, false), &mut scratch, &mut cut);
                        make_path(
                            &mut paths,
                            (PathKind::Closed, Some(PathKind::Eight)),
                            lobe,
                            (true, None),
                            &[v],
                            &cut,
                        );
                        tanglement_kind_of_path.push(Some("EIGHT"));
                    }
                }
                Class::Bli => {
                    let other = cross_partner[ci];
                    if other == usize::MAX {
                        let ends = ch.ends.expect("open");
                        cut.clear();
                        cut_of(
                            &across,
                            steps_of(ch),
                            (
                                false,
                                ends[0] == EndKind::Boundary,
                                ends[1] == EndKind::Boundary,
                            ),
                            &mut scratch,
                            &mut cut,
                        );
                        make_path(
                            &mut paths,
                            (PathKind::BoundaryLoopInside, None),
                            steps_of(ch),
                            (false, ch.ends),
                            &[ch.turns[0].1],
                            &cut,
                        );
                        tanglement_kind_of_path.push(None);
                        continue;
                    }
                    if other < ci {
                        continue; // handled with its partner
                    }
                    let v = ch.turns[0].1;
                    // Each BLI = half toward its first end + half toward its last end, joined at v.
                    // Orient halves from the end to v, as (steps, end kind).
                    let halves = |c: &Chain| -> [(Vec<(u32, u8)>, EndKind); 2] {
                        let t = c.turns[0].0;
                        let ends = c.ends.expect("open");
                        let steps = steps_of(c);
                        let first: Vec<(u32, u8)> = steps[..=t].to_vec();
                        let last: Vec<(u32, u8)> = steps[t + 1..]
                            .iter()
                            .rev()
                            .map(|&(p, e)| (p, 1 - e))
                            .collect();
                        [(first, ends[0]), (last, ends[1])]
                    };
                    let (ha, hb) = (halves(ch), halves(&chains[other]));
                    for kind in [EndKind::Boundary, EndKind::Inside] {
                        let a = ha.iter().find(|h| h.1 == kind);
                        let b = hb.iter().find(|h| h.1 == kind);
                        let (Some(a), Some(b)) = (a, b) else { continue };
                        // a: end -> v; then b reversed: v -> end.
                        let mut steps = a.0.clone();
                        steps.extend(b.0.iter().rev().map(|&(p, e)| (p, 1 - e)));
                        let is_b = kind == EndKind::Boundary;
                        cut.clear();
                        cut_of(&across, &a.0, (false, is_b, false), &mut scratch, &mut cut);
                        cut_of(&across, &b.0, (false, is_b, false), &mut scratch, &mut cut);
                        cut.sort_unstable();
                        let mut odd = Vec::new();
                        for &e in &cut {
                            if odd.last() == Some(&e) {
                                odd.pop();
                            } else {
                                odd.push(e);
                            }
                        }
                        let pk = if is_b {
                            PathKind::BoundaryBoundary
                        } else {
                            PathKind::InsideInside
                        };
                        make_path(
                            &mut paths,
                            (pk, Some(PathKind::Cross)),
                            &steps,
                            (false, Some([kind, kind])),
                            &[v],
                            &odd,
                        );
                        tanglement_kind_of_path.push(Some("CROSS"));
                    }
                }
            }
        }

        (paths, tanglement_kind_of_path)
    };
    let (mut paths, tanglement_kind_of_path) =
        if all_steps.len() >= PAR_PATH_STEPS && rayon::current_num_threads() > 1 {
            // Two ranges of chains with about as many steps each (the steps are in chain order).
            let half = all_steps.len() / 2;
            let m = chains.partition_point(|c| c.steps.start < half);
            let ((mut paths, mut kinds), (p2, k2)) = rayon::join(
                || paths_of_chains(0..m),
                || paths_of_chains(m..chains.len()),
            );
            paths.extend(p2);
            kinds.extend(k2);
            (paths, kinds)
        } else {
            paths_of_chains(0..chains.len())
        };
    // Each piece is on one path at most.
    let mut path_of_piece = vec![u32::MAX; links.len()];
    for (idx, p) in paths.iter().enumerate() {
        for &piece in p.pieces() {
            path_of_piece[piece as usize] = idx as u32;
        }
    }

    // Correspondence and tanglements.
    let mut tanglements: Vec<Tanglement> = Vec::with_capacity(paths.len());
    for i in 0..paths.len() {
        let first = paths[i].pieces()[0];
        paths[i].corresponds_to = path_of_piece[partner(first) as usize];
    }
    for i in 0..paths.len() {
        if paths[i].tanglement != u32::MAX {
            continue;
        }
        let j = paths[i].corresponds_to as usize;
        let members = if j == i || j >= paths.len() {
            TanglementPaths::one(i as u32)
        } else {
            TanglementPaths::two(i as u32, j as u32)
        };
        let kind = match tanglement_kind_of_path[i] {
            Some(k) => k,
            None => tanglement_kind(&paths[i], members.get(1).map(|&m| &paths[m as usize])),
        };
        let mut lv: Vec<u32> = members
            .iter()
            .flat_map(|&m| paths[m as usize].loop_vertices().iter().copied())
            .collect();
        lv.sort_unstable();
        lv.dedup();
        let objs = [
            paths[members[0] as usize].object,
            paths[*members.last().expect("non-empty") as usize].object,
        ];
        let t = tanglements.len() as u32;
        for &m in members.iter() {
            paths[m as usize].tanglement = t;
        }
        tanglements.push(Tanglement {
            kind,
            paths: members,
            objects: [objs[0].min(objs[1]), objs[0].max(objs[1])],
            loop_vertices: lv,
        });
    }
    Ok((paths, tanglements))
}

fn tanglement_kind(p: &Path, q: Option<&Path>) -> &'static str {
    use PathKind::*;
    match (p.kind, q.map(|q| q.kind)) {
        (Closed, _) => "CLOSED",
        (LoopLoop, _) => "LL",
        (BoundaryLoopInside, _) => "BLI",
        (BoundaryLoopBoundary, _) => "BLB",
        (BoundaryLoopLoopBoundary, _) => "BLLB",
        (a, Some(b)) => {
            let mut kinds = [a, b];
            kinds.sort_by_key(|k| match k {
                BoundaryBoundary => 0,
                BoundaryInside => 1,
                _ => 2,
            });
            pair_name(kinds[0], kinds[1])
        }
        (a, None) => a.name(),
    }
}

/// All kinds, in declaration order (`kind as usize` indexes it).
const ALL_KINDS: [PathKind; 10] = [
    PathKind::Closed,
    PathKind::Eight,
    PathKind::LoopLoop,
    PathKind::BoundaryLoopInside,
    PathKind::BoundaryLoopBoundary,
    PathKind::BoundaryLoopLoopBoundary,
    PathKind::Cross,
    PathKind::BoundaryBoundary,
    PathKind::BoundaryInside,
    PathKind::InsideInside,
];

/// The two names one after the other (`"BBII"`): the usual pairs spelled out, every other
/// pair from a table built once (no allocation per tanglement).
fn pair_name(a: PathKind, b: PathKind) -> &'static str {
    use PathKind::*;
    match (a, b) {
        (BoundaryBoundary, InsideInside) => "BBII",
        (BoundaryInside, BoundaryInside) => "BIBI",
        (BoundaryBoundary, BoundaryBoundary) => "BBBB",
        (BoundaryBoundary, BoundaryInside) => "BBBI",
        (BoundaryInside, InsideInside) => "BIII",
        (InsideInside, InsideInside) => "IIII",
        _ => {
            static TABLE: std::sync::OnceLock<Vec<String>> = std::sync::OnceLock::new();
            let table = TABLE.get_or_init(|| {
                ALL_KINDS
                    .iter()
                    .flat_map(|x| {
                        ALL_KINDS
                            .iter()
                            .map(move |y| format!("{}{}", x.name(), y.name()))
                    })
                    .collect()
            });
            &table[a as usize * ALL_KINDS.len() + b as usize]
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The layout `Path` had with three vectors (the oracle for the accessors and `Debug`).
    mod three_vectors {
        use super::super::{EndKind, PathKind};
        #[derive(Debug)]
        #[allow(dead_code)] // read through `Debug` only
        pub struct Path {
            pub kind: PathKind,
            pub split_from: Option<PathKind>,
            pub pieces: Vec<u32>,
            pub closed: bool,
            pub ends: Option<[EndKind; 2]>,
            pub loop_vertices: Vec<u32>,
            pub corresponds_to: u32,
            pub tanglement: u32,
            pub object: u32,
            pub cut_edges: Vec<u32>,
        }
    }

    proptest! {
        /// The three lists come back as given, and `Debug` prints what a derived `Debug` of
        /// the three-vector layout printed (plain and pretty).
        #[test]
        fn path_lists_and_debug_match_three_vectors(
            pieces in proptest::collection::vec(0u32..1000, 1..20),
            cut in proptest::collection::vec(0u32..1000, 0..20),
            lv in proptest::collection::vec(0u32..1000, 0..3),
            closed in proptest::bool::ANY,
            k in 0usize..10,
        ) {
            let kind = ALL_KINDS[k];
            let ends = (!closed).then_some([EndKind::Boundary, EndKind::Inside]);
            let mut p = Path::new((kind, Some(PathKind::Cross)), (closed, ends), pieces.iter().copied(), &cut, &lv, 3);
            p.corresponds_to = 7;
            p.tanglement = 2;
            prop_assert_eq!(p.pieces(), &pieces[..]);
            prop_assert_eq!(p.cut_edges(), &cut[..]);
            prop_assert_eq!(p.loop_vertices(), &lv[..]);
            let old = three_vectors::Path {
                kind,
                split_from: Some(PathKind::Cross),
                pieces: pieces.clone(),
                closed,
                ends,
                loop_vertices: lv.clone(),
                corresponds_to: 7,
                tanglement: 2,
                object: 3,
                cut_edges: cut.clone(),
            };
            prop_assert_eq!(format!("{p:?}"), format!("{old:?}"));
            prop_assert_eq!(format!("{p:#?}"), format!("{old:#?}"));
        }
    }

    /// `ALL_KINDS[k as usize] == k`, and every pair name is the two names one after the other.
    #[test]
    fn kind_table_and_pair_names() {
        for (i, &k) in ALL_KINDS.iter().enumerate() {
            assert_eq!(k as usize, i);
        }
        for &a in &ALL_KINDS {
            for &b in &ALL_KINDS {
                assert_eq!(pair_name(a, b), format!("{}{}", a.name(), b.name()));
            }
        }
    }

    /// One or two ids, read as a slice and printed like a vector.
    #[test]
    fn tanglement_paths_are_a_short_slice() {
        let one = TanglementPaths::one(4);
        let two = TanglementPaths::two(4, 9);
        assert_eq!(&*one, &[4]);
        assert_eq!(&*two, &[4, 9]);
        assert_eq!(format!("{one:?}"), format!("{:?}", vec![4u32]));
        assert_eq!(format!("{two:?}"), format!("{:?}", vec![4u32, 9]));
        assert_eq!((&two).into_iter().copied().collect::<Vec<_>>(), vec![4, 9]);
        assert!(two.contains(&9) && !one.contains(&9));
    }

    proptest! {
        /// The parity bits give the edges seen an odd number of times, sorted (the oracle:
        /// count every edge), for clustered (word scan) and spread-out (sorted list) edges, and
        /// leave the bits clear for the next use.
        #[test]
        fn odd_edges_match_counting(
            batches in proptest::collection::vec(
                proptest::collection::vec((0u32..40, 0u32..3), 0..60), 1..5),
            spread in prop_oneof![Just(1u32), Just(997u32)],
        ) {
            let num_edges = 40 * spread as usize + 1;
            let mut odd = OddEdges::new(num_edges);
            for batch in &batches {
                let mut count = std::collections::BTreeMap::<u32, usize>::new();
                for &(e, reps) in batch {
                    let e = e * spread;
                    for _ in 0..=reps {
                        odd.toggle(e);
                        *count.entry(e).or_default() += 1;
                    }
                }
                let brute: Vec<u32> =
                    count.into_iter().filter(|&(_, c)| c % 2 == 1).map(|(e, _)| e).collect();
                prop_assert_eq!(odd.take(), brute);
                prop_assert!(odd.parity.iter().all(|&w| w == 0));
            }
        }
    }
}
