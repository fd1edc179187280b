//! Tanglement-resolution methods built on the analysis: Cha & Ko 2022 ([`cha_ko`]) and Wicke et
//! al. 2006 ([`wicke`]).

pub mod cha_ko;
pub mod wicke;
