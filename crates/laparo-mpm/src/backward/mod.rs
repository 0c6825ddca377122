//! Hand-derived reverse-mode adjoints of the three stages of a time step (run in reverse order:
//! G2P, grid update, P2G). Notation: ā = ∂L/∂a.
pub mod g2p;
pub mod grid_update;
pub mod p2g;
