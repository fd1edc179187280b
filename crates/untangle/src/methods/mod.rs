//! Tanglement-resolution methods built on the analysis: Cha & Ko 2022 ([`cha_ko`]).

pub mod cha_ko;
