//! Implicit cloth simulation with continuous collision handling that keeps an
//! intersection-free cloth intersection-free — the "full-proof CCH" simulator Cha & Ko 2022
//! (Sec. 1, 4, Fig. 1a) build their untangling into, and the simulator Wicke et al.'s penalty
//! forces run in.
//!
//! - Physics ([`Simulator::step`]): implicit Euler (Baraff & Witkin 1998) with stretch and shear
//!   against each triangle's uv rest shape ([`forces::stretch`]), bending ([`forces::bend`]),
//!   Rayleigh damping, gravity and pinned vertices; the rest shape can be replaced cheaply every
//!   step ([`Simulator::set_rest_uv`], as Cha & Ko edit the uv). World vertices are the nodes,
//!   so seams are simulated once.
//! - Linear algebra: a 3x3 block-sparse matrix ([`sparse`]) and conjugate gradients with the
//!   constraint filter ([`pcg`]).
//! - Opt-in alternative integrator ([`step::Integrator::Projective`]): projective dynamics
//!   (Bouaziz et al. 2014, [`projective`]) with a pre-factored scalar matrix ([`cholesky`]).
//! - Obstacles ([`obstacle`]): static or moving meshes with thickness and friction.
//! - Collision handling ([`collision`]): proximity repulsion, iterated CCD impulses and rigid
//!   impact zones as the fail-safe, with a per-pair [`policy::ContactPolicy`] (skip / thickness)
//!   that Cha & Ko's m-CCH plugs into ([`policy::RedGreen`]).
//! - Every step returns a [`report::StepReport`].
//!
//! Results are bit-identical for any number of threads.

pub mod amg;
pub mod anderson;
pub mod cholesky;
pub mod collision;
pub mod contact;
pub mod forces;
pub mod low_rank;
pub mod near;
pub mod obstacle;
pub mod pcg;
pub mod policy;
pub mod projective;
pub mod refactor;
pub mod report;
pub mod rest;
pub mod sparse;
pub mod step;

pub use collision::impact_zones::ZoneMotion;
pub use obstacle::Obstacle;
pub use policy::{Contact, ContactPolicy, RedGreen, UniformThickness};
pub use report::{CollisionShift, StepReport};
pub use step::{CgPreconditioner, Integrator, SimParams, SimSnapshot, Simulator};
