//! Hand-derived reverse-mode adjoints of the three stages of a time step (run in reverse order:
//! G2P, grid update, P2G). Notation: ā = ∂L/∂a. The reverse pass runs the P2G adjoint of a step and
//! the G2P adjoint of the step before it as one pass ([`fused`]).
pub mod fused;
pub mod g2p;
pub mod grid_update;
pub mod p2g;
