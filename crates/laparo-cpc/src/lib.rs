//! laparo-cpc — Conformal Perspective Correction (thesis Ch. 4).
