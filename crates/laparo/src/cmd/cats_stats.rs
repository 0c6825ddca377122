//! `laparo cats stats` (being written).
