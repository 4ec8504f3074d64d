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

use crate::lighting::{Lighting, Surface};
use crate::optics;
use crate::physics::StaticBox;
use crate::realism::{CameraAsBuilt, Effects, Finish, LampSpec, Preset, RigAsBuilt};
use crate::render::{Frame, Light, RenderScene, ShadedTriangle, render_radiance, render_stereo};
use crate::sensor::{FixedPattern, read_out};
use crate::world::WorldFile;
use mesh::{Model, StereoCalibration, TriMesh};
use nalgebra::{Point3, Vector3};
use rand::{SeedableRng, rngs::Xoshiro256PlusPlus};
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;

/// Relative spread of one part's albedo about its model's: uniform within +-10%.
pub const ALBEDO_SPREAD: f64 = 0.10;
/// The arm's links: painted metal.
pub const ARM_FINISH: Finish = Finish { specular: 0.1, roughness: 0.35, texture: 0.0, albedo_scale: 1.0 };

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
}

impl Imaging {
    pub fn new(world: &WorldFile) -> Imaging {
        let effects = world.effects();
        let lamps = match &world.lamps {
            Some(l) => l.clone(),
            None => vec![LampSpec::from_light(&world.light)],
        };
        Imaging {
            preset: world.realism,
            effects,
            nominal: crate::rig::calibration(&world.cameras),
            rig: RigAsBuilt::new(&world.cameras, &effects, world.as_built_seed),
            lamps,
            light: Light::from(&world.light),
            noise_sigma: world.render.noise_sigma,
            table_texture: world.table.texture as f32,
        }
    }

    /// The true cameras (their pinholes; the lenses are in [`Self::rig`]).
    pub fn true_calibration(&self) -> StereoCalibration {
        self.rig.calibration()
    }

    /// The finish of a fixed box: the table's with its texture.
    pub fn static_finish(&self, b: &StaticBox) -> Finish {
        match b.name.as_str() {
            "table" => Finish { specular: 0.02, roughness: 0.7, texture: self.table_texture, albedo_scale: 1.0 },
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

    /// Shades meshes for drawing.
    pub fn scene(&self, meshes: impl IntoIterator<Item = (u32, TriMesh, Finish)>) -> RenderScene {
        RenderScene::with_finishes(meshes, &self.light)
    }

    /// Both cameras' frames of `scene`; `seed` draws the capture's noise.
    pub fn render_stereo(&self, scene: &RenderScene, seed: u64) -> (Frame, Frame) {
        if !self.effects.any_imaging() {
            return render_stereo(scene, &self.rig.calibration(), self.noise_sigma, seed);
        }
        let lighting = Lighting::new(&self.lamps, self.light, &self.effects, &scene.corners());
        rayon::join(
            || self.render_camera(scene, &lighting, &self.rig.left, seed.wrapping_mul(2)),
            || self.render_camera(scene, &lighting, &self.rig.right, seed.wrapping_mul(2).wrapping_add(1)),
        )
    }

    /// One realistic camera's frame.
    pub fn render_camera(&self, scene: &RenderScene, lighting: &Lighting, cam: &CameraAsBuilt, seed: u64) -> Frame {
        let virt = optics::virtual_pinhole(cam);
        let eye = cam.pinhole.centre();
        let shade = |t: &ShadedTriangle, point: &Point3<f64>| {
            lighting.shade(&Surface { point: *point, normal: t.normal, albedo: t.albedo, finish: t.finish }, &eye)
        };
        let seen = render_radiance(scene, &virt, &shade);
        let (w, h) = (cam.pinhole.width as usize, cam.pinhole.height as usize);
        let cam_from_world = cam.pinhole.cam_from_world();
        let mut frame = Frame { width: w, height: h, image: vec![0; w * h], depth: vec![0.0; w * h], ids: vec![0; w * h] };
        let mut radiance = vec![0.0f32; w * h];
        let mut vignette = vec![1.0f32; w * h];
        radiance
            .par_chunks_mut(w)
            .zip(vignette.par_chunks_mut(w))
            .zip(frame.depth.par_chunks_mut(w).zip(frame.ids.par_chunks_mut(w)))
            .enumerate()
            .for_each(|(v, ((rad, vig), (depth, ids)))| {
                for u in 0..w {
                    let (x, y) = optics::ideal_normalised(cam, u as f64, v as f64);
                    let (vx, vy) = (virt.fx * x + virt.cx, virt.fy * y + virt.cy);
                    rad[u] = optics::bilinear(&seen.radiance, seen.width, seen.height, vx, vy);
                    if self.effects.vignetting {
                        vig[u] = optics::vignetting(x, y, cam.lens.vignetting_exponent);
                    }
                    let nearest = (vy.round() as usize).min(seen.height - 1) * seen.width
                        + (vx.round() as usize).min(seen.width - 1);
                    let t = seen.centre[nearest];
                    if t != u32::MAX {
                        let tri = &scene.triangles[t as usize];
                        let n = cam_from_world.rotation * tri.normal;
                        let a = cam_from_world * tri.corners[0];
                        let z = n.dot(&a.coords) / n.dot(&Vector3::new(x, y, 1.0));
                        if z.is_finite() && z > 0.0 {
                            depth[u] = z as f32;
                            ids[u] = tri.id;
                        }
                    }
                }
            });
        if self.effects.blur {
            let sigma: Vec<f32> = frame
                .depth
                .iter()
                .map(|&d| {
                    let d = if d > 0.0 { d as f64 } else { cam.lens.focus_distance_m };
                    cam.lens.blur_sigma_px(d, cam.pixel_pitch_mm) as f32
                })
                .collect();
            radiance = optics::blur_by_sigma(&radiance, w, &sigma);
        }
        radiance.iter_mut().zip(&vignette).for_each(|(r, v)| *r *= v);
        frame.image = if self.effects.sensor {
            let pattern = FixedPattern::new(&cam.sensor, w * h, cam.pattern_seed);
            read_out(&cam.sensor, &pattern, &radiance, w, seed)
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
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15).wrapping_add(y as u64));
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
