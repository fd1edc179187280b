//! One module per subcommand.

pub mod check;
pub mod demo;
pub mod fix;
pub mod fix_wicke;
pub mod layers;
pub mod scene;
pub mod simulate;
