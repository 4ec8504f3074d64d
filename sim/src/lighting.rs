//! Light in the realistic cell: lamps of some size with fall-off and soft cast shadows, a sky,
//! glossy reflection and the table's faint texture.
//!
//! Brightness is in the ideal renderer's units (a white matte surface under irradiance 1 is 1):
//!
//! ```text
//! brightness = albedo (1 - s) (E_lamps + E_sky) + s E_lamps (m + 8) / 8 (n·h)^m
//! E_lamps = Σ_lamp-points I_k max(0, n·l_k) / d_k² · lit_k,   E_sky = sky (1 + n_z) / 2
//! ```
//!
//! Each lamp is a disc facing the origin, sampled at [`LAMP_POINTS`] points on a Vogel spiral,
//! so a point of the scene is lit by the fraction of the lamp it sees: umbra, penumbra and
//! light. On the table's plane (most of what the cameras see) each point's shadow is cast
//! exactly, every occluder's lit faces projected from the lamp point onto the plane
//! ([`TableShadows`]); elsewhere each point has a shadow map (a depth image from that point of
//! what stands above the table). `s` is the finish's specular fraction; `h` the half-way vector
//! to the lamp's centre; `m = 2 / roughness² - 2` (to an even number) the normalised
//! Blinn-Phong exponent.
//!
//! Written by hand: the shadow maps reuse nothing of a GPU, and the shading is a few lines.

use crate::realism::{Effects, Finish, LampSpec};
use crate::render::Light;
use crate::shadows::{ON_TABLE_M, ShadowMap, TableShadows, table_extent};
use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

pub use crate::shadows::LAMP_POINTS;

/// One point of a lamp.
struct LampPoint {
    position: Point3<f64>,
    /// `I / LAMP_POINTS`: irradiance at 1 m facing the point.
    intensity: f64,
    shadow: Option<ShadowMap>,
}

/// A lamp: its centre (for the gloss's highlight) and its points (for light and shadow).
struct Lamp {
    centre: Point3<f64>,
    points: Vec<LampPoint>,
    /// The points' positions and intensities side by side, for [`Lamp::light`].
    xyzi: [[f32; LAMP_POINTS]; 4],
    /// Its points' shadows on the table's plane, when shadows are on and the scene has it.
    on_table: Option<TableShadows>,
    /// The table top's extent on its plane (`[lo, hi]`, x and y), with `on_table`.
    table_top: Option<([f64; 2], [f64; 2])>,
}

/// The light of a realistic scene, ready to shade any surface point.
pub struct Lighting {
    lamps: Vec<Lamp>,
    sky: f64,
    /// Used when lamps are off: the ideal preset's distant light.
    distant: Light,
    lamps_on: bool,
    specular_on: bool,
    texture_on: bool,
    /// The texture laid out over the table, when the caller gave its extent.
    texture: Option<std::sync::Arc<TextureGrid>>,
}

/// [`table_texture`] sampled every [`TEXTURE_STEP_M`] over a rectangle and looked up
/// bilinearly: the noise's three octaves cost a dozen hashes a point, the grid four loads.
#[derive(Debug, Clone)]
pub struct TextureGrid {
    x0: f64,
    y0: f64,
    w: usize,
    h: usize,
    /// The texture in 1/127ths (its effect on the albedo, 6% of it, in steps of 0.05%): a
    /// quarter of the floats' memory, so the look-ups stay in the cache.
    values: Vec<i8>,
}

/// Spacing of the texture grid: half the finest octave's 4 mm.
pub const TEXTURE_STEP_M: f64 = 0.002;

impl TextureGrid {
    /// The grid over `[-half_x, half_x] x [-half_y, half_y]`.
    pub fn new(half_x: f64, half_y: f64) -> TextureGrid {
        let (w, h) =
            ((2.0 * half_x / TEXTURE_STEP_M).ceil() as usize + 2, (2.0 * half_y / TEXTURE_STEP_M).ceil() as usize + 2);
        let (x0, y0) = (-half_x, -half_y);
        let values = (0..w * h)
            .into_par_iter()
            .map(|k| {
                let t = table_texture(x0 + (k % w) as f64 * TEXTURE_STEP_M, y0 + (k / w) as f64 * TEXTURE_STEP_M);
                (t * 127.0).round() as i8
            })
            .collect();
        TextureGrid { x0, y0, w, h, values }
    }

    pub fn at(&self, x: f64, y: f64) -> f32 {
        const PER_M: f64 = 1.0 / TEXTURE_STEP_M;
        let (gx, gy) = ((x - self.x0) * PER_M, (y - self.y0) * PER_M);
        if !(gx >= 0.0 && gy >= 0.0 && gx < (self.w - 1) as f64 && gy < (self.h - 1) as f64) {
            return table_texture(x, y);
        }
        // Both coordinates are positive here: truncation is the floor.
        let (i, j) = (gx as usize, gy as usize);
        let (ax, ay) = ((gx - i as f64) as f32, (gy - j as f64) as f32);
        let k = j * self.w + i;
        let v = |k: usize| self.values[k] as f32 / 127.0;
        (1.0 - ay) * ((1.0 - ax) * v(k) + ax * v(k + 1)) + ay * ((1.0 - ax) * v(k + self.w) + ax * v(k + self.w + 1))
    }
}

/// What the shading needs of a surface.
#[derive(Debug, Clone, Copy)]
pub struct Surface {
    pub point: Point3<f64>,
    pub normal: Vector3<f64>,
    pub albedo: f32,
    pub finish: Finish,
}

impl Lighting {
    /// Builds each lamp's points and (with shadows on) their shadow maps of `occluders`
    /// (world-space triangles).
    pub fn new(lamps: &[LampSpec], distant: Light, effects: &Effects, occluders: &[[Point3<f64>; 3]]) -> Lighting {
        Self::with_texture(lamps, distant, effects, occluders, None)
    }

    /// As [`Self::new`], with the table's texture laid out on a grid beforehand.
    pub fn with_texture(
        lamps: &[LampSpec],
        distant: Light,
        effects: &Effects,
        occluders: &[[Point3<f64>; 3]],
        texture: Option<std::sync::Arc<TextureGrid>>,
    ) -> Lighting {
        let mut built: Vec<Lamp> = Vec::new();
        if effects.lamps {
            for lamp in lamps {
                let centre = lamp.position();
                let intensity = lamp.irradiance * centre.coords.norm_squared() / LAMP_POINTS as f64;
                let points: Vec<LampPoint> = disc_points(centre, lamp.radius_m)
                    .into_iter()
                    .map(|position| LampPoint { position, intensity, shadow: None })
                    .collect();
                let xyzi = [0, 1, 2, 3].map(|c| {
                    std::array::from_fn(|k| {
                        let p: &LampPoint = &points[k];
                        (if c < 3 { p.position[c] } else { p.intensity }) as f32
                    })
                });
                built.push(Lamp { centre, points, xyzi, on_table: None, table_top: None });
            }
            if effects.shadows {
                let extent = table_extent(occluders);
                // With a table, the shadow maps need only what stands above its plane: the
                // plane itself is looked up in `TableShadows`, and a point under it is in the
                // table's shadow where its way to the lamp crosses the table top.
                let above: Vec<[Point3<f64>; 3]> = match extent {
                    Some(_) => occluders.iter().filter(|t| t.iter().any(|c| c.z > ON_TABLE_M)).copied().collect(),
                    None => occluders.to_vec(),
                };
                let points: Vec<&mut LampPoint> = built.iter_mut().flat_map(|l| l.points.iter_mut()).collect();
                points.into_par_iter().for_each(|p| p.shadow = Some(ShadowMap::new(p.position, &above)));
                if let Some((lo, hi)) = extent {
                    built.par_iter_mut().for_each(|l| {
                        l.on_table = Some(TableShadows::new(
                            &l.points.iter().map(|p| p.position).collect::<Vec<_>>(),
                            occluders,
                            lo,
                            hi,
                        ));
                        l.table_top = Some((lo, hi));
                    });
                }
            }
        }
        Lighting {
            lamps: built,
            sky: distant.ambient,
            distant,
            lamps_on: effects.lamps,
            specular_on: effects.specular,
            texture_on: effects.table_texture,
            texture,
        }
    }

    /// Brightness of `s` seen from `eye`.
    pub fn shade(&self, s: &Surface, eye: &Point3<f64>) -> f32 {
        let n = s.normal;
        let mut albedo = s.albedo * s.finish.albedo_scale;
        if self.texture_on && s.finish.texture > 0.0 {
            let grain = match &self.texture {
                Some(grid) => grid.at(s.point.x, s.point.y),
                None => table_texture(s.point.x, s.point.y),
            };
            albedo *= 1.0 + s.finish.texture * grain;
        }
        let spec_frac = if self.specular_on { s.finish.specular } else { 0.0 };
        if !self.lamps_on {
            let lambert = n.dot(&self.distant.towards_light).max(0.0);
            let diffuse = self.distant.ambient + self.distant.diffuse * lambert;
            let gloss = if spec_frac > 0.0 {
                let view = (eye - s.point).normalize();
                self.distant.diffuse * lambert * lobe(&n, &self.distant.towards_light, &view, s.finish.roughness)
            } else {
                0.0
            };
            return albedo * (1.0 - spec_frac) * diffuse as f32 + spec_frac * gloss as f32;
        }
        let sky = self.sky * 0.5 * (1.0 + n.z);
        let (mut diffuse, mut gloss) = (0.0, 0.0);
        let view = unit(eye - s.point);
        for lamp in &self.lamps {
            let e = lamp_irradiance(lamp, &s.point, &n).0;
            diffuse += e;
            if spec_frac > 0.0 && e > 0.0 {
                // The highlight's shape from the lamp's centre; its strength from the light
                // that reaches the point (the disc's few centimetres widen it little).
                gloss += e * lobe(&n, &unit(lamp.centre - s.point), &view, s.finish.roughness);
            }
        }
        albedo * (1.0 - spec_frac) * (diffuse + sky) as f32 + spec_frac * gloss as f32
    }

    /// Irradiance the lamps alone put on a point with normal `n`, unshadowed and shadowed:
    /// what a test compares a point in shadow with.
    pub fn lamp_irradiance(&self, point: &Point3<f64>, n: &Vector3<f64>) -> (f64, f64) {
        let (mut open, mut shadowed) = (0.0, 0.0);
        for lamp in &self.lamps {
            let (lit, all) = lamp_irradiance(lamp, point, n);
            shadowed += lit;
            open += all;
        }
        (open, shadowed)
    }

    /// The sky's irradiance on a surface with normal `n`.
    pub fn sky_irradiance(&self, n: &Vector3<f64>) -> f64 {
        self.sky * 0.5 * (1.0 + n.z)
    }
}

/// The irradiance one lamp puts on a point, and what it would put there unshadowed: each of
/// its points' light, by the cosine and the square of the distance, times the fraction its
/// shadow lets through. On the table's plane the shadows are looked up in [`TableShadows`].
/// Elsewhere half the points' shadow maps are tested first (every other one, spread over the
/// disc): when they agree that the point is wholly lit or wholly in shadow, so are the rest
/// (only a penumbra pays for all of them).
fn lamp_irradiance(lamp: &Lamp, point: &Point3<f64>, n: &Vector3<f64>) -> (f64, f64) {
    let (light, distance) = lamp.light(point, n);
    let on_plane = point.z.abs() < ON_TABLE_M && n.z > 0.9999;
    if let Some(lit) = lamp.on_table.as_ref().filter(|_| on_plane).and_then(|t| t.lit(point.x, point.y)) {
        let total = light.iter().zip(lit).map(|(e, f)| *e as f64 * f).sum();
        return (total, light.iter().map(|e| *e as f64).sum());
    }
    let open: f64 = light.iter().map(|e| *e as f64).sum();
    let under_table = |k: usize| {
        let Some(([x0, y0], [x1, y1])) = lamp.table_top.filter(|_| point.z < -ON_TABLE_M) else { return false };
        // Where the way from the point up to the lamp point crosses the table's plane.
        let s = lamp.points[k].position;
        let t = -point.z / (s.z - point.z);
        let (x, y) = (point.x + t * (s.x - point.x), point.y + t * (s.y - point.y));
        (x0..=x1).contains(&x) && (y0..=y1).contains(&y)
    };
    let lit = |k: usize| match &lamp.points[k].shadow {
        _ if light[k] <= 0.0 => 1.0,
        _ if under_table(k) => 0.0,
        Some(map) => map.lit(point, n, distance[k] as f64),
        None => 1.0,
    };
    let (mut total, mut all_lit, mut all_dark) = (0.0, true, true);
    for k in (0..LAMP_POINTS).step_by(2) {
        let f = lit(k);
        total += light[k] as f64 * f;
        all_lit &= f >= 1.0;
        all_dark &= f <= 0.0;
    }
    for k in (1..LAMP_POINTS).step_by(2) {
        // Wholly lit or dark by the points tested: the others' light is taken to do the same.
        let f = if all_lit {
            1.0
        } else if all_dark {
            0.0
        } else {
            lit(k)
        };
        total += light[k] as f64 * f;
    }
    (total, open)
}

impl Lamp {
    /// Each point's irradiance on a surface at `point` with normal `n` (cosine over the square
    /// of the distance, 0 facing away), unshadowed, and its distance: in single precision and
    /// side by side, so the eight are worked out at once.
    fn light(&self, point: &Point3<f64>, n: &Vector3<f64>) -> ([f32; LAMP_POINTS], [f32; LAMP_POINTS]) {
        let [x, y, z, intensity] = &self.xyzi;
        let (p, n) = ([point.x as f32, point.y as f32, point.z as f32], [n.x as f32, n.y as f32, n.z as f32]);
        let mut light = [0.0f32; LAMP_POINTS];
        let mut distance = [0.0f32; LAMP_POINTS];
        for k in 0..LAMP_POINTS {
            let (dx, dy, dz) = (x[k] - p[0], y[k] - p[1], z[k] - p[2]);
            let facing = n[0] * dx + n[1] * dy + n[2] * dz;
            let d2 = dx * dx + dy * dy + dz * dz;
            let d = d2.sqrt();
            distance[k] = d;
            // cos / d² = (n . to) / d³
            light[k] = if facing > 0.0 { intensity[k] * facing / (d2 * d) } else { 0.0 };
        }
        (light, distance)
    }
}

/// Normalised Blinn-Phong, as a multiple of the lamp's irradiance: `(m + 8) / 8 (n·h)^m`.
/// The exponent is rounded to an even number: an even power of `n.h` is a power of
/// `(n.(l + v))² / |l + v|²`, a few products and no root (the highlight's width moves by a few
/// percent at most).
fn lobe(n: &Vector3<f64>, l: &Vector3<f64>, view: &Vector3<f64>, roughness: f32) -> f64 {
    let half = l + view;
    let along = n.dot(&half);
    if along <= 0.0 {
        return 0.0;
    }
    let r = roughness.max(0.02) as f64;
    let pairs = ((1.0 / (r * r) - 1.0).round() as i32).max(1);
    let m = 2.0 * pairs as f64;
    (m + 8.0) / 8.0 * (along * along / half.norm_squared()).powi(pairs)
}

/// `v / |v|` with one division, not three.
fn unit(v: Vector3<f64>) -> Vector3<f64> {
    v * (1.0 / v.norm())
}

/// `LAMP_POINTS` points spread evenly over a disc of `radius` at `centre`, facing the origin
/// (a Vogel spiral: equal areas, no rings).
fn disc_points(centre: Point3<f64>, radius: f64) -> Vec<Point3<f64>> {
    let axis = (-centre.coords).try_normalize(1e-12).unwrap_or(-Vector3::z());
    let helper = if axis.z.abs() < 0.9 { Vector3::z() } else { Vector3::x() };
    let u = axis.cross(&helper).normalize();
    let v = axis.cross(&u);
    (0..LAMP_POINTS)
        .map(|i| {
            let r = radius * ((i as f64 + 0.5) / LAMP_POINTS as f64).sqrt();
            let a = i as f64 * 2.399_963_229_728_653; // the golden angle
            centre + u * (r * a.cos()) + v * (r * a.sin())
        })
        .collect()
}

/// The table's faint texture: smooth value noise in the table's plane, in -1..1, at three
/// scales (4, 13 and 40 mm), as a laminate's grain.
pub fn table_texture(x: f64, y: f64) -> f32 {
    let octave = |scale: f64, salt: u64| value_noise(x / scale, y / scale, salt);
    (0.5 * octave(0.040, 1) + 0.3 * octave(0.013, 2) + 0.2 * octave(0.004, 3)) as f32
}

/// Smoothly interpolated random values on the integer lattice, in -1..1.
fn value_noise(x: f64, y: f64, salt: u64) -> f64 {
    let (fx, fy) = (x.floor(), y.floor());
    let (ix, iy) = (fx as i64, fy as i64);
    let smooth = |t: f64| t * t * (3.0 - 2.0 * t);
    let (sx, sy) = (smooth(x - fx), smooth(y - fy));
    let at = |i: i64, j: i64| lattice(i, j, salt);
    let top = at(ix, iy) * (1.0 - sx) + at(ix + 1, iy) * sx;
    let bottom = at(ix, iy + 1) * (1.0 - sx) + at(ix + 1, iy + 1) * sx;
    top * (1.0 - sy) + bottom * sy
}

/// A hash of a lattice point to -1..1 (SplitMix64's finaliser).
fn lattice(i: i64, j: i64, salt: u64) -> f64 {
    let mut z = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (j as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ salt.wrapping_mul(0x1656_67B1_9E37_79F9);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 52) as f64 - 1.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::realism::{EffectsSpec, Preset};

    fn effects() -> Effects {
        Effects::resolve(Preset::Realistic, &EffectsSpec::default())
    }

    /// A 1 m floor square at z = 0 and a 10 cm square plate 10 cm over its middle.
    fn floor_and_plate() -> Vec<[Point3<f64>; 3]> {
        let square = |h: f64, z: f64| {
            let p = |x: f64, y: f64| Point3::new(x, y, z);
            vec![[p(-h, -h), p(h, -h), p(h, h)], [p(-h, -h), p(h, h), p(-h, h)]]
        };
        let mut t = square(0.5, 0.0);
        t.extend(square(0.05, 0.1));
        t
    }

    fn lamp_overhead(radius: f64) -> LampSpec {
        LampSpec { position_m: [0.0, 0.0, 1.0], radius_m: radius, irradiance: 0.8 }
    }

    fn distant() -> Light {
        Light { towards_light: Vector3::z(), diffuse: 0.75, ambient: 0.2 }
    }

    #[test]
    fn a_point_in_a_parts_shadow_is_darker_by_the_lamps_share() {
        let lighting = Lighting::new(&[lamp_overhead(0.02)], distant(), &effects(), &floor_and_plate());
        let matte = Finish::MATTE;
        let up = Vector3::z();
        let surface = |x: f64| Surface { point: Point3::new(x, 0.0, 0.0), normal: up, albedo: 0.5, finish: matte };
        let eye = Point3::new(0.0, -0.5, 0.8);
        let (shadowed, open) = (lighting.shade(&surface(0.0), &eye), lighting.shade(&surface(0.3), &eye));
        // Under the plate the floor has only the sky; in the open the lamp too, falling off with
        // the square of the distance and the cosine: by hand at (0.3, 0, 0), d² = 1.09.
        let sky = 0.2;
        assert!((shadowed - 0.5 * sky as f32).abs() < 1e-6, "{shadowed}");
        let lamp_at_03: f64 = lighting.lamps[0]
            .points
            .iter()
            .map(|p| {
                let to = p.position - Point3::new(0.3, 0.0, 0.0);
                p.intensity * to.z / to.norm().powi(3)
            })
            .sum();
        assert!((lamp_at_03 - 0.8 / 1.09f64.powf(1.5)).abs() < 2e-3, "{lamp_at_03}");
        assert!((open - 0.5 * (sky + lamp_at_03) as f32).abs() < 1e-5, "{open}");
        let (unshadowed, reached) = lighting.lamp_irradiance(&Point3::new(0.0, 0.0, 0.0), &up);
        assert!((unshadowed - 0.8).abs() < 2e-3 && reached == 0.0, "{unshadowed} {reached}");
    }

    #[test]
    fn a_larger_lamp_casts_a_penumbra_that_a_small_one_does_not() {
        let (small, large) = (
            Lighting::new(&[lamp_overhead(0.005)], distant(), &effects(), &floor_and_plate()),
            Lighting::new(&[lamp_overhead(0.3)], distant(), &effects(), &floor_and_plate()),
        );
        let up = Vector3::z();
        // Just outside the plate's shadow edge (x = 0.05 / 0.9 = 0.0556 m from an overhead point).
        let fraction = |l: &Lighting, x: f64| {
            let (open, lit) = l.lamp_irradiance(&Point3::new(x, 0.0, 0.0), &up);
            lit / open
        };
        assert_eq!(fraction(&small, 0.045), 0.0);
        assert_eq!(fraction(&small, 0.065), 1.0);
        let half = fraction(&large, 0.056);
        assert!(half > 0.1 && half < 0.9, "the large lamp's penumbra: {half}");
    }

    #[test]
    fn gloss_depends_on_the_viewpoint_and_diffuse_light_does_not() {
        let lighting = Lighting::new(&[lamp_overhead(0.02)], distant(), &effects(), &[]);
        let glossy = Finish { specular: 0.2, roughness: 0.3, ..Finish::MATTE };
        let s = Surface { point: Point3::new(0.1, 0.0, 0.0), normal: Vector3::z(), albedo: 0.5, finish: glossy };
        // The mirror direction of the lamp seen from (0.1, 0, 0) is towards (0.2, 0, 1).
        let (mirror, aside) =
            (lighting.shade(&s, &Point3::new(0.2, 0.0, 1.0)), lighting.shade(&s, &Point3::new(-0.6, 0.0, 0.5)));
        assert!(mirror > 1.5 * aside, "highlight {mirror} vs {aside}");
        let matte = Surface { finish: Finish::MATTE, ..s };
        assert_eq!(
            lighting.shade(&matte, &Point3::new(0.2, 0.0, 1.0)),
            lighting.shade(&matte, &Point3::new(-0.6, 0.0, 0.5))
        );
    }

    #[test]
    fn the_texture_is_faint_smooth_and_centred() {
        let values: Vec<f32> = (0..2000).map(|i| table_texture(i as f64 * 0.0037, (i % 37) as f64 * 0.011)).collect();
        let mean = values.iter().sum::<f32>() / values.len() as f32;
        assert!(mean.abs() < 0.1, "{mean}");
        assert!(values.iter().all(|v| v.abs() <= 1.0));
        assert!((table_texture(0.1, 0.1) - table_texture(0.1001, 0.1)).abs() < 0.02);
    }
}
