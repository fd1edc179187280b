//! Internal forces of the cloth and their Jacobians: in-plane stretch and shear measured
//! against each triangle's uv rest shape ([`stretch`]), and bending across interior edges
//! ([`bend`]).

pub mod bend;
pub mod stretch;
