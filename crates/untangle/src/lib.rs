//! # untangle
//!
//! Find, classify and remove self- and inter-penetrations ("tanglements") in cloth and garment
//! meshes. The library implements:
//!
//! - the global intersection analysis of Wicke et al. 2006 (Sec. 4) with the red/green colouring
//!   of Cha & Ko 2022 (Sec. 3): [`analysis`];
//! - the uv-space update and m-CCH contact policy of Cha & Ko 2022 (Sec. 4-8): [`methods::cha_ko`];
//! - procedural scenes with known answers: [`scenes`];
//! - pictures of meshes and per-step charts (software rasteriser, no image dependency): [`render`];
//! - an implicit cloth simulator with full-proof continuous collision handling and a per-pair
//!   contact policy (Cha & Ko 2022, Sec. 5.2): [`sim`].
//!
//! It has no command-line or terminal dependencies; the `untangle` binary is built on top of it.

#![warn(missing_docs)]

pub mod analysis;
pub mod broad;
pub mod error;
pub mod fsio;
pub mod geom;
pub mod implicit;
pub mod mesh;
pub mod methods;
pub mod pool;
pub mod radix;
pub mod render;
pub mod scenes;
pub mod sim;

pub use error::{Error, Result};
