//! laparo-mpm — differentiable MLS-MPM with exact gradients, 2D and 3D (thesis §5.2.3–5.2.4).
