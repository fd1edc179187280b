//! One module per subcommand.

pub mod check;
pub mod demo;
pub mod fix;
pub mod layers;
pub mod scene;
pub mod simulate;
