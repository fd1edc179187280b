//! Tanglement-resolution methods built on the analysis: Cha & Ko 2022 ([`cha_ko`]), Wicke et
//! al. 2006 ([`wicke`]), and the two in stages ([`combined`], ours); [`fewest`] keeps a loop's
//! fewest-pair state.

pub mod cha_ko;
pub mod combined;
pub mod fewest;
pub mod wicke;
