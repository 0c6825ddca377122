//! Tetrahedralisation of closed surfaces, mesh quality and incisions (filled by the meshing work).
