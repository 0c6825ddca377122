//! Quadratic-tetrahedron quasi-static FEM (filled by the solver work).
