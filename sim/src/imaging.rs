//! How the cell's cameras form their images, by the world's `realism` preset: one entry point
//! for everything that renders the cell (`marvin render`, the robot server's `capture`, the
//! evaluations and the benchmarks).
//!
//! Ideal (every imaging effect off): the first renderer, unchanged ([`crate::render::render`]).
//! Realistic, per camera: the scene through the camera's virtual pinhole at its true mounting,
//! shaded per pixel under the lamps with their soft shadows, the sky and the surfaces' gloss
//! ([`crate::lighting`]); then resampled through the lens's distortion, blurred by depth and
//! vignetted ([`crate::optics`]); then read out by the sensor ([`crate::sensor`]). The depth
//! and id maps are the true camera's, pixel for pixel of the distorted image.

use crate::lighting::{Lighting, Surface, TextureGrid};
use crate::optics;
use crate::physics::StaticBox;
use crate::realism::{CameraAsBuilt, Effects, Finish, LampSpec, Preset, RigAsBuilt};
use crate::render::{Frame, Light, RenderScene, ShadedTriangle, render_radiance, render_stereo};
use crate::sensor::{FixedPattern, read_out};
use crate::world::WorldFile;
use mesh::{Model, PinholeCamera, StereoCalibration, TriMesh};
use nalgebra::Point3;
use rand::{SeedableRng, rngs::Xoshiro256PlusPlus};
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;
use std::sync::Arc;

/// Relative spread of one part's albedo about its model's: uniform within +-10%.
pub const ALBEDO_SPREAD: f64 = 0.10;
/// The arm's links: painted metal.
pub const ARM_FINISH: Finish = Finish { specular: 0.1, roughness: 0.35, texture: 0.0, albedo_scale: 1.0 };

/// What a realistic camera's every frame shares, worked out once: the virtual pinhole, where
/// each pixel looks in it, the pixel's ideal ray and vignetting, and the sensor's patterns.
#[derive(Debug)]
pub struct CameraImaging {
    virt: PinholeCamera,
    /// Per pixel: the virtual pinhole's coordinates it takes its light from.
    source: Vec<(f32, f32)>,
    /// Per pixel: that point's bilinear look-up in the virtual image, worked out once.
    taps: Vec<Tap>,
    /// The virtual image's pixels some look-up reads: the only ones worth shading.
    needed: Vec<bool>,
    /// The real image's width.
    width: usize,
    vignette: Vec<f32>,
    pattern: FixedPattern,
}

/// A bilinear look-up: the top-left pixel of the four, the weights of the right and lower ones,
/// and the pixel nearest (for the depth and id maps).
#[derive(Debug, Clone, Copy)]
struct Tap {
    top_left: u32,
    ax: f32,
    ay: f32,
    nearest: u32,
}

impl Tap {
    fn new((x, y): (f32, f32), w: usize, h: usize) -> Tap {
        let (x, y) = (x.clamp(0.0, (w - 1) as f32 - 1e-3), y.clamp(0.0, (h - 1) as f32 - 1e-3));
        let (i, j) = (x as usize, y as usize);
        let nearest = (y.round() as usize) * w + x.round() as usize;
        Tap { top_left: (j * w + i) as u32, ax: x - i as f32, ay: y - j as f32, nearest: nearest as u32 }
    }

    fn sample(&self, image: &[f32], w: usize) -> f32 {
        let k = self.top_left as usize;
        let (ax, ay) = (self.ax, self.ay);
        (1.0 - ay) * ((1.0 - ax) * image[k] + ax * image[k + 1])
            + ay * ((1.0 - ax) * image[k + w] + ax * image[k + w + 1])
    }
}

impl CameraImaging {
    fn new(cam: &CameraAsBuilt, effects: &Effects) -> CameraImaging {
        let virt = optics::virtual_pinhole(cam);
        let (w, h) = (cam.pinhole.width as usize, cam.pinhole.height as usize);
        let ray: Vec<(f64, f64)> =
            (0..w * h).into_par_iter().map(|i| optics::ideal_normalised(cam, (i % w) as f64, (i / w) as f64)).collect();
        let source: Vec<(f32, f32)> =
            ray.iter().map(|&(x, y)| ((virt.fx * x + virt.cx) as f32, (virt.fy * y + virt.cy) as f32)).collect();
        let vignette = ray
            .iter()
            .map(
                |&(x, y)| if effects.vignetting { optics::vignetting(x, y, cam.lens.vignetting_exponent) } else { 1.0 },
            )
            .collect();
        let pattern = FixedPattern::new(&cam.sensor, w * h, cam.pattern_seed);
        let (vw, vh) = (virt.width as usize, virt.height as usize);
        let taps: Vec<Tap> = source.iter().map(|&s| Tap::new(s, vw, vh)).collect();
        let mut needed = vec![false; vw * vh];
        for t in &taps {
            let k = t.top_left as usize;
            for i in [k, k + 1, k + vw, k + vw + 1] {
                needed[i] = true;
            }
        }
        CameraImaging { virt, source, taps, needed, width: w, vignette, pattern }
    }
}

/// Everything that forms the cell's images.
#[derive(Debug, Clone)]
pub struct Imaging {
    pub preset: Preset,
    pub effects: Effects,
    /// The cameras as the world file gives them: what anyone who has not calibrated knows.
    pub nominal: StereoCalibration,
    /// The cameras as built: the truth.
    pub rig: RigAsBuilt,
    pub lamps: Vec<LampSpec>,
    /// The world's distant light (the ideal preset's, and the sky's strength).
    pub light: Light,
    /// The ideal preset's Gaussian noise, grey levels.
    pub noise_sigma: f64,
    table_texture: f32,
    /// The realistic cameras' shared work (empty in the ideal preset).
    cameras: Option<Arc<[CameraImaging; 2]>>,
    texture: Option<Arc<TextureGrid>>,
}

impl Imaging {
    pub fn new(world: &WorldFile) -> Imaging {
        let effects = world.effects();
        let lamps = match &world.lamps {
            Some(l) => l.clone(),
            None => vec![LampSpec::from_light(world.light.direction, world.light.diffuse)],
        };
        let rig = crate::rig::as_built(&world.cameras, &effects, world.as_built_seed);
        let cameras = effects.any_imaging().then(|| {
            let (l, r) =
                rayon::join(|| CameraImaging::new(&rig.left, &effects), || CameraImaging::new(&rig.right, &effects));
            Arc::new([l, r])
        });
        let [sx, sy] = world.table.size_m;
        let texture = (effects.any_imaging() && effects.table_texture && world.table.texture > 0.0)
            .then(|| Arc::new(TextureGrid::new(sx / 2.0, sy / 2.0)));
        Imaging {
            preset: world.realism,
            effects,
            nominal: crate::rig::calibration(&world.cameras),
            rig,
            lamps,
            light: Light::from(&world.light),
            noise_sigma: world.render.noise_sigma,
            table_texture: world.table.texture as f32,
            cameras,
            texture,
        }
    }

    /// The true cameras (their pinholes; the lenses are in [`Self::rig`]).
    pub fn true_calibration(&self) -> StereoCalibration {
        self.rig.calibration()
    }

    /// The finish of a fixed box: the table's with its texture.
    pub fn static_finish(&self, b: &StaticBox) -> Finish {
        match b.name.as_str() {
            // A matte laminate: its grain, no gloss.
            "table" => Finish { specular: 0.0, roughness: 1.0, texture: self.table_texture, albedo_scale: 1.0 },
            "floor" => Finish::MATTE,
            _ => Finish { specular: 0.04, roughness: 0.5, texture: 0.0, albedo_scale: 1.0 },
        }
    }

    /// The finish of object `id` of `model` in the scene of `seed`: the model's gloss, and an
    /// albedo of its own (with `albedo_variation` on).
    pub fn object_finish(&self, model: &Model, id: u32, seed: u64) -> Finish {
        let scale = if self.effects.albedo_variation {
            let h = splitmix(seed.wrapping_mul(0x2545_F491_4F6C_DD1D) ^ id as u64);
            1.0 + ALBEDO_SPREAD * (2.0 * ((h >> 11) as f64 / (1u64 << 53) as f64) - 1.0)
        } else {
            1.0
        };
        Finish {
            specular: model.finish.specular as f32,
            roughness: model.finish.roughness as f32,
            texture: 0.0,
            albedo_scale: scale as f32,
        }
    }

    /// Where pixel `(u, v)` of the left (`right = false`) or right realistic camera takes its
    /// light from: the virtual pinhole the scene is drawn through, and the point of its image
    /// (`None` in the ideal preset, which draws through the camera itself).
    pub fn light_source(&self, right: bool, u: usize, v: usize) -> Option<(&PinholeCamera, (f64, f64))> {
        let cam = &self.cameras.as_ref()?[usize::from(right)];
        let (x, y) = cam.source[v * cam.width + u];
        Some((&cam.virt, (x as f64, y as f64)))
    }

    /// Shades meshes for drawing.
    pub fn scene(&self, meshes: impl IntoIterator<Item = (u32, TriMesh, Finish)>) -> RenderScene {
        RenderScene::with_finishes(meshes, &self.light)
    }

    /// Both cameras' frames of `scene`; `seed` draws the capture's noise.
    pub fn render_stereo(&self, scene: &RenderScene, seed: u64) -> (Frame, Frame) {
        let Some(cameras) = &self.cameras else {
            return render_stereo(scene, &self.rig.calibration(), self.noise_sigma, seed);
        };
        let lighting =
            Lighting::with_texture(&self.lamps, self.light, &self.effects, &scene.corners(), self.texture.clone());
        rayon::join(
            || self.render_camera(scene, &lighting, &self.rig.left, &cameras[0], seed.wrapping_mul(2)),
            || self.render_camera(scene, &lighting, &self.rig.right, &cameras[1], seed.wrapping_mul(2).wrapping_add(1)),
        )
    }

    /// One realistic camera's frame.
    fn render_camera(
        &self,
        scene: &RenderScene,
        lighting: &Lighting,
        cam: &CameraAsBuilt,
        shared: &CameraImaging,
        seed: u64,
    ) -> Frame {
        let virt = &shared.virt;
        let eye = cam.pinhole.centre();
        let shade = |t: &ShadedTriangle, point: &Point3<f64>| {
            lighting.shade(&Surface { point: *point, normal: t.normal, albedo: t.albedo, finish: t.finish }, &eye)
        };
        let seen = render_radiance(scene, virt, &shared.needed, &shade);
        let (w, h) = (cam.pinhole.width as usize, cam.pinhole.height as usize);
        let mut frame =
            Frame { width: w, height: h, image: vec![0; w * h], depth: vec![0.0; w * h], ids: vec![0; w * h] };
        let mut radiance = vec![0.0f32; w * h];
        radiance
            .par_chunks_mut(w)
            .zip(frame.depth.par_chunks_mut(w).zip(frame.ids.par_chunks_mut(w)))
            .enumerate()
            .for_each(|(v, (rad, (depth, ids)))| {
                for u in 0..w {
                    let tap = &shared.taps[v * w + u];
                    rad[u] = tap.sample(&seen.radiance, seen.width);
                    let t = seen.centre[tap.nearest as usize];
                    if t != u32::MAX {
                        let (vx, vy) = shared.source[v * w + u];
                        let [p, q, r] = seen.inv_z[t as usize];
                        let z = 1.0 / (p * vx as f64 + q * vy as f64 + r);
                        if z.is_finite() && z > 0.0 {
                            depth[u] = z as f32;
                            ids[u] = seen.ids[t as usize];
                        }
                    }
                }
            });
        if self.effects.blur {
            let variance: Vec<f32> = frame
                .depth
                .par_iter()
                .map(|&d| {
                    let d = if d > 0.0 { d as f64 } else { cam.lens.focus_distance_m };
                    cam.lens.blur_variance_px2(d, cam.pixel_pitch_mm) as f32
                })
                .collect();
            radiance = optics::blur_by_variance(&radiance, w, &variance);
        }
        radiance.iter_mut().zip(&shared.vignette).for_each(|(r, v)| *r *= v);
        frame.image = if self.effects.sensor {
            read_out(&cam.sensor, &shared.pattern, &radiance, w, seed)
        } else {
            gaussian_read_out(&radiance, w, self.noise_sigma, seed)
        };
        frame
    }
}

/// Without the sensor model: the ideal preset's grey levels, `255 x radiance` plus Gaussian
/// noise, rounded.
fn gaussian_read_out(radiance: &[f32], w: usize, sigma: f64, seed: u64) -> Vec<u8> {
    let noise = Normal::new(0.0f32, sigma as f32).expect("noise sigma is checked to be >= 0");
    let mut out = vec![0u8; radiance.len()];
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        let mut rng =
            Xoshiro256PlusPlus::seed_from_u64(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15).wrapping_add(y as u64));
        for (x, o) in row.iter_mut().enumerate() {
            let grain = if sigma > 0.0 { noise.sample(&mut rng) } else { 0.0 };
            *o = ((255.0 * radiance[y * w + x] + grain).clamp(0.0, 255.0) + 0.5) as u8;
        }
    });
    out
}

/// SplitMix64's finaliser: a well-mixed 64-bit hash.
fn splitmix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}
