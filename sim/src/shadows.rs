//! Shadows of the realistic cell's lamps: which lamp points a surface point sees.
//!
//! - [`TableShadows`]: on the table's plane (`z = 0`, most of what the cameras see), each lamp
//!   point's shadows cast exactly -- every occluder's lit faces projected from the point onto
//!   the plane, as a central projection maps a triangle to a triangle -- one bit a point in a
//!   grid of [`TABLE_CELL_M`] cells.
//! - [`ShadowMap`]: elsewhere (parts, bins, the arm), a depth image from the lamp point of
//!   what stands above the table, framed on it.
//!
//! The scene is closed solids, so only the faces that face a lamp point cast its shadows.

use crate::render::{area2, clip_near, edge_functions, inv_z_plane, run_along_row};
use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};
use rayon::prelude::*;

/// Points each lamp is sampled at (shadows have this many steps of penumbra, smoothed by the
/// maps' bilinear look-ups and the lens's blur).
pub const LAMP_POINTS: usize = 8;
/// Shadow maps are this many texels square.
const MAP_SIZE: usize = 384;
/// Widest half field of view of a shadow map, radians.
const MAX_HALF_FOV: f64 = 1.2;
/// Depth tolerance of a shadow test, metres, beyond the normal offset.
const SHADOW_BIAS_M: f32 = 1.5e-3;

/// A depth image seen from one point of a lamp.
pub(crate) struct ShadowMap {
    /// `view_from_world` as a matrix and a shift (cheaper to apply than a quaternion), with
    /// the focal length and the centre folded in: `(fx, fy, z) = m p + t` gives the texel
    /// `(fx / z + c, fy / z + c)`. Single precision: a texel is 3 mm, a float's step at 2 m
    /// a fraction of a micrometre.
    m: [[f32; 3]; 3],
    t: [f32; 3],
    focal: f64,
    /// Inverse depth along the view axis, 1/metres, of the nearest surface; 0 where nothing was
    /// drawn.
    inv_depth: Vec<f32>,
}

/// The shadows a lamp's points cast on the table's plane (`z = 0`, the world's table top,
/// where most of what the cameras see lies): every triangle above the plane projected onto it
/// from each point -- exactly, as a central projection onto a plane maps a triangle to a
/// triangle -- and drawn into a grid of [`TABLE_CELL_M`] cells, one bit a point. A point of the
/// plane looks its shadows up here (four cells, bilinearly) instead of in eight shadow maps.
pub(crate) struct TableShadows {
    x0: f64,
    y0: f64,
    w: usize,
    h: usize,
    /// Bit `k` of a cell: lamp point `k`'s light does not reach the cell's centre.
    bits: Vec<u8>,
    /// Cells under a part resting on the table (under its bottom faces): in its shadow, but no
    /// camera sees them, and a point beside the part must not take their dark into its
    /// interpolation (it would darken a pixel-wide line along every part's lit foot).
    under: Vec<u8>,
}

/// A part's face lower than this over the table, facing down, is a foot on it, metres.
pub(crate) const FOOT_M: f64 = 2e-3;

/// Cells of the table's shadow grid, metres.
pub(crate) const TABLE_CELL_M: f64 = 0.002;

/// How near the table's plane a point must be to be on it, metres.
pub(crate) const ON_TABLE_M: f64 = 1e-5;

impl TableShadows {
    /// The shadows on the plane within `[lo, hi]` (its receivers' extent) of `occluders`.
    pub(crate) fn new(
        points: &[Point3<f64>],
        occluders: &[[Point3<f64>; 3]],
        lo: [f64; 2],
        hi: [f64; 2],
    ) -> TableShadows {
        let (w, h) = (
            ((hi[0] - lo[0]) / TABLE_CELL_M).ceil() as usize + 1,
            ((hi[1] - lo[1]) / TABLE_CELL_M).ceil() as usize + 1,
        );
        // Each point's shadow outline on the plane, in cell units, then drawn band by band of
        // rows in parallel.
        let mut cast: Vec<(u8, [[f64; 2]; 3])> = Vec::new();
        for (k, p) in points.iter().enumerate() {
            let s = *p;
            for t in occluders {
                if t.iter().all(|c| c.z <= ON_TABLE_M) || !faces(t, &s) {
                    // On or under the plane: no shadow on it from above. Facing away: a closed
                    // solid's shadow is its lit faces' shadows.
                    continue;
                }
                // The part below the lamp point (what is above it lights nothing under it),
                // projected from the point onto z = 0.
                let flip = |c: Point3<f64>| Point3::new(c.x, c.y, s.z - 1e-3 - c.z);
                let outline: Vec<[f64; 2]> = clip_near(&t.map(flip), 0.0)
                    .into_iter()
                    .map(|c| {
                        let c = flip(c);
                        let f = s.z / (s.z - c.z);
                        [(s.x + (c.x - s.x) * f - lo[0]) / TABLE_CELL_M, (s.y + (c.y - s.y) * f - lo[1]) / TABLE_CELL_M]
                    })
                    .collect();
                for j in 1..outline.len().saturating_sub(1) {
                    cast.push((1 << k, [outline[0], outline[j], outline[j + 1]]));
                }
            }
        }
        let mut bits = vec![0u8; w * h];
        let band = h.div_ceil(16).max(1);
        bits.par_chunks_mut(band * w).enumerate().for_each(|(b, rows)| {
            for (bit, tri) in &cast {
                fill(rows, w, b * band, tri, *bit);
            }
        });
        let feet: Vec<[[f64; 2]; 3]> = occluders
            .iter()
            .filter(|t| t.iter().all(|c| c.z.abs() <= FOOT_M) && (t[1] - t[0]).cross(&(t[2] - t[0])).z < 0.0)
            .map(|t| t.map(|c| [(c.x - lo[0]) / TABLE_CELL_M, (c.y - lo[1]) / TABLE_CELL_M]))
            .collect();
        let mut under = vec![0u8; w * h];
        for foot in &feet {
            fill(&mut under, w, 0, foot, 1);
        }
        TableShadows { x0: lo[0], y0: lo[1], w, h, bits, under }
    }

    /// Per lamp point, the fraction (0-1) of its light that reaches `(x, y)` on the plane.
    pub(crate) fn lit(&self, x: f64, y: f64) -> Option<[f64; LAMP_POINTS]> {
        let (gx, gy) = ((x - self.x0) / TABLE_CELL_M - 0.5, (y - self.y0) / TABLE_CELL_M - 0.5);
        if !(gx >= 0.0 && gy >= 0.0 && gx < (self.w - 1) as f64 && gy < (self.h - 1) as f64) {
            return None;
        }
        let (i, j) = (gx as usize, gy as usize);
        let (ax, ay) = (gx - i as f64, gy - j as f64);
        let k = j * self.w + i;
        let any = self.bits[k] | self.bits[k + 1] | self.bits[k + self.w] | self.bits[k + self.w + 1];
        if any == 0 {
            return Some([1.0; LAMP_POINTS]); // the common case: in no point's shadow
        }
        let at = [k, k + 1, k + self.w, k + self.w + 1];
        let mut weight = [(1.0 - ax) * (1.0 - ay), ax * (1.0 - ay), (1.0 - ax) * ay, ax * ay];
        // Cells under a part do not speak for a point beside it.
        let open: f64 = at.iter().zip(&weight).filter(|(c, _)| self.under[**c] == 0).map(|(_, wt)| wt).sum();
        if open > 0.0 && open < 1.0 {
            for (c, wt) in at.iter().zip(weight.iter_mut()) {
                *wt = if self.under[*c] == 0 { *wt / open } else { 0.0 };
            }
        }
        Some(std::array::from_fn(|b| {
            at.iter().zip(&weight).map(|(c, wt)| if self.bits[*c] & (1 << b) == 0 { *wt } else { 0.0 }).sum()
        }))
    }
}

/// Sets `bit` in every cell of `rows` (whole rows of `w` cells, the first of them row `row0`)
/// whose centre lies in the triangle `v` (in cell units, cell `i`'s centre at `i + 0.5`).
fn fill(rows: &mut [u8], w: usize, row0: usize, v: &[[f64; 2]; 3], bit: u8) {
    let area = area2(v);
    if area.abs() < 1e-12 {
        return;
    }
    let edges = edge_functions(v, area);
    let top = v.iter().map(|c| c[1]).fold(f64::MAX, f64::min) - 0.5;
    let bottom = v.iter().map(|c| c[1]).fold(f64::MIN, f64::max) - 0.5;
    let last_row = (row0 + rows.len() / w) as f64 - 1.0;
    let (y0, y1) = (top.ceil().max(row0 as f64) as i64, bottom.floor().min(last_row) as i64);
    let last = (w - 1) as f64;
    for y in y0..=y1 {
        // The run of cell centres inside all three edges along this row.
        if let Some((lo, hi)) = run_along_row(&edges, y as f64 + 0.5, 0.5, last) {
            rows[(y as usize - row0) * w..][lo..=hi].iter_mut().for_each(|cell| *cell |= bit);
        }
    }
}

/// The extent `[lo, hi]` (x, y) of the triangles lying on the table's plane facing up, if any.
pub(crate) fn table_extent(triangles: &[[Point3<f64>; 3]]) -> Option<([f64; 2], [f64; 2])> {
    let mut extent: Option<([f64; 2], [f64; 2])> = None;
    for t in triangles {
        let up = (t[1] - t[0]).cross(&(t[2] - t[0]));
        if t.iter().all(|c| c.z.abs() < ON_TABLE_M) && up.z > 0.0 {
            for c in t {
                let (lo, hi) = extent.get_or_insert(([c.x, c.y], [c.x, c.y]));
                *lo = [lo[0].min(c.x), lo[1].min(c.y)];
                *hi = [hi[0].max(c.x), hi[1].max(c.y)];
            }
        }
    }
    extent
}

impl ShadowMap {
    /// Draws the depth of `triangles` seen from `from`, looking at the origin.
    /// The map looks at the middle of the triangles' bounding box and takes in all of it: a
    /// point it does not see lies in no triangle's shadow (its way to the lamp point passes
    /// none of them), so the texels are as fine as the occluders' extent allows.
    pub(crate) fn new(from: Point3<f64>, triangles: &[[Point3<f64>; 3]]) -> ShadowMap {
        let corners = bounding_corners(triangles);
        let middle = corners.iter().fold(Vector3::zeros(), |a, c| a + c.coords) / 8.0;
        let forward = (middle - from.coords).try_normalize(1e-9).unwrap_or(-Vector3::z());
        let up = if forward.z.abs() < 0.9 { Vector3::z() } else { Vector3::y() };
        // View frame: z forward, x right, y down, as the cameras' frames.
        let rot = UnitQuaternion::face_towards(&forward, &-up);
        let world_from_view = Isometry3::from_parts(from.coords.into(), rot);
        let view_from_world = world_from_view.inverse();
        // The widest the box's corners lie off the axis (tangent), with a margin, capped where
        // a corner lies beside or behind the lamp point.
        let reach = corners
            .iter()
            .map(|c| {
                let q = view_from_world * c;
                if q.z < 0.05 { MAX_HALF_FOV.tan() } else { q.x.abs().max(q.y.abs()) / q.z }
            })
            .fold(0.05f64, f64::max);
        let focal = (MAP_SIZE as f64 / 2.0) / (1.05 * reach).min(MAX_HALF_FOV.tan());
        let r = *view_from_world.rotation.to_rotation_matrix().matrix();
        let s = view_from_world.translation.vector;
        let row =
            |i: usize, scale: f64| [(r[(i, 0)] * scale) as f32, (r[(i, 1)] * scale) as f32, (r[(i, 2)] * scale) as f32];
        let m = [row(0, focal), row(1, focal), row(2, 1.0)];
        let t = [(s.x * focal) as f32, (s.y * focal) as f32, s.z as f32];
        let mut map = ShadowMap { m, t, focal, inv_depth: vec![0.0; MAP_SIZE * MAP_SIZE] };
        // The nearest surface from the lamp point is always one that faces it (the scene is
        // closed solids).
        for t in triangles.iter().filter(|t| faces(t, &from)) {
            map.draw(&t.map(|p| view_from_world * p));
        }
        map
    }

    fn to_texel(&self, p: &Point3<f64>) -> (f64, f64) {
        let c = (MAP_SIZE as f64 - 1.0) / 2.0;
        (self.focal * p.x / p.z + c, self.focal * p.y / p.z + c)
    }

    /// Rasterises one view-space triangle, clipped at a near plane, keeping the nearest depth.
    fn draw(&mut self, tri: &[Point3<f64>; 3]) {
        const NEAR: f64 = 0.02;
        let polygon = clip_near(tri, NEAR);
        if polygon.len() < 3 {
            return;
        }
        let px: Vec<[f64; 3]> = polygon
            .iter()
            .map(|p| {
                let (x, y) = self.to_texel(p);
                [x, y, 1.0 / p.z]
            })
            .collect();
        for k in 1..px.len() - 1 {
            self.fill([px[0], px[k], px[k + 1]]);
        }
    }

    /// Fills one triangle of texel coordinates and inverse depths, row by row over the span
    /// that its three edges leave (big triangles, the table's, cost one pass over their texels).
    fn fill(&mut self, v: [[f64; 3]; 3]) {
        let area = area2(&v);
        if area.abs() < 1e-12 {
            return;
        }
        let edges = edge_functions(&v, area);
        let [pz, qz, rz] = inv_z_plane(&v, area);
        let max = (MAP_SIZE - 1) as f64;
        let y0 = v.iter().map(|c| c[1]).fold(f64::MAX, f64::min).ceil().max(0.0);
        let y1 = v.iter().map(|c| c[1]).fold(f64::MIN, f64::max).floor().min(max);
        let mut y = y0;
        while y <= y1 {
            if let Some((lo, hi)) = run_along_row(&edges, y, 0.0, max) {
                let row = &mut self.inv_depth[y as usize * MAP_SIZE..][lo..=hi];
                let (start, step) = ((pz * lo as f64 + qz * y + rz) as f32, pz as f32);
                for (k, d) in row.iter_mut().enumerate() {
                    *d = d.max(start + step * k as f32);
                }
            }
            y += 1.0;
        }
    }

    /// The fraction (0-1) of this lamp point's light that reaches `p` (with normal `n`, `d`
    /// from the lamp point): the four nearest texels' tests, weighted bilinearly. The point is
    /// first moved a texel and a half along its normal, so a surface does not shadow itself.
    pub(crate) fn lit(&self, p: &Point3<f64>, n: &Vector3<f64>, d: f64) -> f64 {
        let off = 1.5 * d / self.focal;
        let p = [(p.x + n.x * off) as f32, (p.y + n.y * off) as f32, (p.z + n.z * off) as f32];
        let dot = |r: &[f32; 3], t: f32| r[0] * p[0] + r[1] * p[1] + r[2] * p[2] + t;
        let (fx, fy, z) = (dot(&self.m[0], self.t[0]), dot(&self.m[1], self.t[1]), dot(&self.m[2], self.t[2]));
        if z <= 0.0 {
            return 1.0;
        }
        let (r, c) = (1.0 / z, (MAP_SIZE as f32 - 1.0) / 2.0);
        let (x, y) = (fx * r + c, fy * r + c);
        if !(x >= 0.0 && y >= 0.0 && x < (MAP_SIZE - 1) as f32 && y < (MAP_SIZE - 1) as f32) {
            return 1.0; // outside the map: nothing there to cast a shadow
        }
        let (i, j) = (x as usize, y as usize);
        let (ax, ay) = (x - i as f32, y - j as f32);
        // Lit where the point (pulled back by the bias) is no deeper than the nearest surface
        // drawn: `1/z_map <= 1/z_point`, with the division multiplied out.
        let depth = z - SHADOW_BIAS_M;
        let k = j * MAP_SIZE + i;
        let near = &self.inv_depth[k..k + MAP_SIZE + 2];
        let at = |o: usize| -> f32 { if near[o] * depth <= 1.0 { 1.0 } else { 0.0 } };
        ((1.0 - ay) * ((1.0 - ax) * at(0) + ax * at(1)) + ay * ((1.0 - ax) * at(MAP_SIZE) + ax * at(MAP_SIZE + 1)))
            as f64
    }
}

/// Whether a counter-clockwise triangle faces the point `from` (its outside towards it).
pub(crate) fn faces(t: &[Point3<f64>; 3], from: &Point3<f64>) -> bool {
    (t[1] - t[0]).cross(&(t[2] - t[0])).dot(&(from - t[0])) > 0.0
}

/// The eight corners of the triangles' bounding box (all at the origin if there are none).
pub(crate) fn bounding_corners(triangles: &[[Point3<f64>; 3]]) -> [Point3<f64>; 8] {
    let (mut lo, mut hi) = (Point3::from([f64::MAX; 3]), Point3::from([f64::MIN; 3]));
    for p in triangles.iter().flatten() {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    if triangles.is_empty() {
        (lo, hi) = (Point3::origin(), Point3::origin());
    }
    std::array::from_fn(|k| {
        Point3::new(
            if k & 1 == 0 { lo.x } else { hi.x },
            if k & 2 == 0 { lo.y } else { hi.y },
            if k & 4 == 0 { lo.z } else { hi.z },
        )
    })
}
