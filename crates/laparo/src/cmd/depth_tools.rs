//! `laparo depth perturb` and `laparo depth reproject` (being written).
