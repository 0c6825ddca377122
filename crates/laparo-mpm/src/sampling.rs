//! Particle sampling from meshes (being written).
