//! Wicke et al. 2006, *Untangling Cloth With Boundaries*, Sec. 5: intersection handling from
//! the global intersection analysis (Sec. 4, [`crate::analysis`]). Point-to-point
//! correspondences between the intersecting parts are extrapolated from the intersection paths
//! to their inside regions by thin-plate RBF fits in parameter space (Sec. 5.1), penalty forces
//! pull the inside parts toward their targets while collision handling lets them pass
//! (Sec. 5.2), and BI/BI pairs, which have no inside region, are pushed toward the nearest cloth
//! boundary (Sec. 5.3).
//!
//! It is the untangler Cha & Ko 2022 compare against (part of their "PREV-DCHs"), here as a
//! second method of `untangle fix` (`--method wicke`) and as a peer in the benchmarks.
//!
//! ```text
//! let (am, _) = AnalysisMesh::single(&garment.mesh)?;
//! let mut r = WickeResolver::new(&garment, &am, WickeParams::default())?;
//! let outcome = r.run(|step| println!("{} pairs", step.intersecting_pairs))?;
//! ```
//!
//! Modules: [`rbf`] (the thin-plate fit, Eq. 2-3), [`correspondence`] (samples along paths,
//! per-panel maps, uv point location), [`forces`] (Eq. 4, Eq. 5-7, the free parts),
//! [`resolve`] (the loop with the simulator and its collision policy).

pub mod correspondence;
pub mod forces;
pub mod rbf;
pub mod resolve;

pub use forces::{ForceParams, ForceReport};
pub use rbf::ThinPlate;
pub use resolve::{WickeOutcome, WickeParams, WickeResolver, WickeStep};
