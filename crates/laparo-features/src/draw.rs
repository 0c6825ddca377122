//! Match pictures (thesis Fig. 4.8): the two images side by side, one line per match in its own
//! colour (green = correct, red = wrong by convention), a small circle at each end.
use laparo_core::image::Image;

use crate::keypoint::{Keypoint, Match};

/// Green used for correct matches.
pub const GREEN: [u8; 3] = [0, 220, 0];
/// Red used for wrong matches.
pub const RED: [u8; 3] = [235, 20, 20];
/// Yellow used for unverifiable matches.
pub const YELLOW: [u8; 3] = [240, 200, 0];

fn put(img: &mut Image<u8>, x: i64, y: i64, c: [u8; 3]) {
    if x >= 0 && y >= 0 && (x as usize) < img.width && (y as usize) < img.height {
        img.pixel_mut(x as usize, y as usize)[..3].copy_from_slice(&c);
    }
}

/// Bresenham line from (x0, y0) to (x1, y1), px.
pub fn draw_line(img: &mut Image<u8>, (x0, y0): (i64, i64), (x1, y1): (i64, i64), c: [u8; 3]) {
    let (dx, dy) = ((x1 - x0).abs(), -(y1 - y0).abs());
    let (sx, sy) = (if x0 < x1 { 1 } else { -1 }, if y0 < y1 { 1 } else { -1 });
    let (mut x, mut y, mut err) = (x0, y0, dx + dy);
    loop {
        put(img, x, y, c);
        if x == x1 && y == y1 {
            break;
        }
        let e2 = 2 * err;
        if e2 >= dy {
            err += dy;
            x += sx;
        }
        if e2 <= dx {
            err += dx;
            y += sy;
        }
    }
}

/// Circle outline of radius `r` px (midpoint algorithm).
pub fn draw_circle(img: &mut Image<u8>, (cx, cy): (i64, i64), r: i64, c: [u8; 3]) {
    let (mut x, mut y, mut d) = (r, 0i64, 1 - r);
    while x >= y {
        for (a, b) in [(x, y), (y, x), (-y, x), (-x, y), (-x, -y), (-y, -x), (y, -x), (x, -y)] {
            put(img, cx + a, cy + b, c);
        }
        y += 1;
        if d < 0 {
            d += 2 * y + 1;
        } else {
            x -= 1;
            d += 2 * (y - x) + 1;
        }
    }
}

/// Image 1 and image 2 side by side (RGB, heights padded with black), a line per match from
/// `kp1[m.i1]` to `kp2[m.i2]` in `colours[k]` (green if `colours` is shorter than `matches`).
pub fn draw_matches(
    img1: &Image<u8>,
    img2: &Image<u8>,
    kp1: &[Keypoint],
    kp2: &[Keypoint],
    matches: &[Match],
    colours: &[[u8; 3]],
) -> Image<u8> {
    let (a, b) = (img1.to_rgb(), img2.to_rgb());
    let (w, h) = (a.width + b.width, a.height.max(b.height));
    let mut out = Image::filled(w, h, 3, 0u8);
    for y in 0..a.height {
        let dst = (y * w) * 3;
        out.data[dst..dst + a.width * 3].copy_from_slice(&a.data[y * a.width * 3..(y + 1) * a.width * 3]);
    }
    for y in 0..b.height {
        let dst = (y * w + a.width) * 3;
        out.data[dst..dst + b.width * 3].copy_from_slice(&b.data[y * b.width * 3..(y + 1) * b.width * 3]);
    }
    let off = a.width as i64;
    for (k, m) in matches.iter().enumerate() {
        let (Some(p), Some(q)) = (kp1.get(m.i1 as usize), kp2.get(m.i2 as usize)) else { continue };
        let c = colours.get(k).copied().unwrap_or(GREEN);
        let p = (p.x.round() as i64, p.y.round() as i64);
        let q = (q.x.round() as i64 + off, q.y.round() as i64);
        draw_line(&mut out, p, q, c);
        draw_circle(&mut out, p, 3, c);
        draw_circle(&mut out, q, 3, c);
    }
    out
}
