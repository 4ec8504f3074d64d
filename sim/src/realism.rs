//! How real the cell is: the `realism` preset of a world file, the switches of its effects, and
//! the specs of what a real cell has and the ideal one does not -- lenses, sensors, camera
//! mountings, lamps, surface finishes and an arm built off its drawing.
//!
//! `realism = "ideal"` is the cell as it was first simulated (a perfect pinhole, one distant
//! light, Gaussian noise): its images are bit for bit what that renderer drew. `"realistic"`
//! (the default) turns every effect on; `[effects]` switches each one on its own. Every value
//! has a default that a 512x512 CCD camera with an 8 mm lens about 0.9 m from the table, a
//! lamp over the cell and a small arm would have.
//!
//! What differs from cell to cell but not from scene to scene (how the cameras were bolted on,
//! their sensors' fixed patterns, the arm's offsets) is drawn from `as_built_seed`; what
//! differs between parts (their albedo) from the scene's seed.

use mesh::PinholeCamera;
use mesh::distortion::PlumbBob;
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rand::{SeedableRng, rngs::StdRng};
use rand_distr::{Distribution, Normal};
use rapier3d_urdf::urdf_rs;
use serde::Deserialize;

/// The two presets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Preset {
    /// The cell as first simulated; kept so that every earlier figure can be reproduced.
    Ideal,
    /// Every effect on.
    #[default]
    Realistic,
}

/// Each effect on its own; an effect left out follows the preset.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EffectsSpec {
    /// Lens distortion (`plumb_bob`).
    pub distortion: Option<bool>,
    /// Defocus and the lens's own blur.
    pub blur: Option<bool>,
    /// Fall-off of light towards the image corners.
    pub vignetting: Option<bool>,
    /// The sensor model (shot and read noise, fixed patterns, gain, black level, response);
    /// off, the ideal preset's Gaussian noise of `render.noise_sigma`.
    pub sensor: Option<bool>,
    /// Cameras mounted off their nominal poses.
    pub mounting: Option<bool>,
    /// Lamps with position and size and a sky; off, the ideal preset's distant light.
    pub lamps: Option<bool>,
    /// Cast shadows from the lamps.
    pub shadows: Option<bool>,
    /// Glossy reflection.
    pub specular: Option<bool>,
    /// Each part's albedo off its model's.
    pub albedo_variation: Option<bool>,
    /// A faintly textured table top.
    pub table_texture: Option<bool>,
    /// The arm as built: joint zero offsets, link length errors, encoder resolution.
    pub arm_as_built: Option<bool>,
}

/// The effects as switched for one world.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, Deserialize)]
pub struct Effects {
    pub distortion: bool,
    pub blur: bool,
    pub vignetting: bool,
    pub sensor: bool,
    pub mounting: bool,
    pub lamps: bool,
    pub shadows: bool,
    pub specular: bool,
    pub albedo_variation: bool,
    pub table_texture: bool,
    pub arm_as_built: bool,
}

impl Effects {
    pub fn resolve(preset: Preset, spec: &EffectsSpec) -> Effects {
        let on = preset == Preset::Realistic;
        let or = |o: Option<bool>| o.unwrap_or(on);
        Effects {
            distortion: or(spec.distortion),
            blur: or(spec.blur),
            vignetting: or(spec.vignetting),
            sensor: or(spec.sensor),
            mounting: or(spec.mounting),
            lamps: or(spec.lamps),
            shadows: or(spec.shadows),
            specular: or(spec.specular),
            albedo_variation: or(spec.albedo_variation),
            table_texture: or(spec.table_texture),
            arm_as_built: or(spec.arm_as_built),
        }
    }

    /// Whether any effect changes how images are formed (the ideal renderer serves otherwise).
    pub fn any_imaging(&self) -> bool {
        let e = self;
        e.distortion
            || e.blur
            || e.vignetting
            || e.sensor
            || e.lamps
            || e.shadows
            || e.specular
            || e.albedo_variation
            || e.table_texture
    }
}

/// A camera's lens. Left out, each value has the default of an 8 mm f/2 lens focused at 0.9 m.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LensSpec {
    /// `[k1, k2, p1, p2, k3]`, as ROS's `D`.
    pub distortion: Option<[f64; 5]>,
    /// Focal length, millimetres: with `focal_px` it sets the pixel pitch.
    pub focal_length_mm: Option<f64>,
    pub f_number: Option<f64>,
    /// Distance of the plane in focus, along the optical axis, metres.
    pub focus_distance_m: Option<f64>,
    /// The lens's own blur (diffraction, aberrations): a Gaussian of this sigma, pixels.
    pub psf_sigma_px: Option<f64>,
    /// Natural vignetting, `cos^n` of the angle off the axis: 4 is the classic law.
    pub vignetting_exponent: Option<f64>,
}

/// A camera's lens as used.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, Deserialize)]
pub struct Lens {
    pub distortion: PlumbBob,
    pub focal_length_mm: f64,
    pub f_number: f64,
    pub focus_distance_m: f64,
    pub psf_sigma_px: f64,
    pub vignetting_exponent: f64,
}

impl Lens {
    fn resolve(spec: &LensSpec, side: Side) -> Lens {
        // Two lenses of one make: barrel distortion a few percent apart, each centred a little off.
        let distortion = match side {
            Side::Left => [-0.20, 0.09, 3e-4, -2e-4, 0.0],
            Side::Right => [-0.19, 0.08, -2e-4, 3e-4, 0.0],
        };
        Lens {
            distortion: PlumbBob::from_d(spec.distortion.unwrap_or(distortion)),
            focal_length_mm: spec.focal_length_mm.unwrap_or(8.0),
            f_number: spec.f_number.unwrap_or(2.0),
            focus_distance_m: spec.focus_distance_m.unwrap_or(0.9),
            psf_sigma_px: spec.psf_sigma_px.unwrap_or(0.45),
            vignetting_exponent: spec.vignetting_exponent.unwrap_or(4.0),
        }
    }

    /// Diameter of the thin lens's circle of confusion, pixels, for a point at `depth_m` along
    /// the axis, with pixels `pitch_mm` wide: `c = A f |z - z_f| / (z (z_f - f))`, `A = f / N`.
    pub fn circle_of_confusion_px(&self, depth_m: f64, pitch_mm: f64) -> f64 {
        let (f, z, zf) = (self.focal_length_mm, depth_m * 1e3, self.focus_distance_m * 1e3);
        let aperture = f / self.f_number;
        aperture * f * (z - zf).abs() / (z * (zf - f)) / pitch_mm
    }

    /// Variance of the whole blur at `depth_m`, px²: the lens's own and the defocus disc's (a
    /// uniform disc of diameter `c` has a variance of `c² / 16` along each axis).
    pub fn blur_variance_px2(&self, depth_m: f64, pitch_mm: f64) -> f64 {
        let disc = self.circle_of_confusion_px(depth_m, pitch_mm);
        self.psf_sigma_px.powi(2) + disc * disc / 16.0
    }

    /// Sigma of the whole blur at `depth_m`, pixels.
    pub fn blur_sigma_px(&self, depth_m: f64, pitch_mm: f64) -> f64 {
        self.blur_variance_px2(depth_m, pitch_mm).sqrt()
    }
}

/// A camera's sensor. Left out, each value has the default of a 512x512 CCD; the two cameras'
/// gains and black levels differ by a few percent, as two real cameras' do.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorSpec {
    /// Electrons a pixel holds before it saturates.
    pub full_well_e: Option<f64>,
    /// Electrons collected from a white surface (albedo 1) under irradiance 1.
    pub white_e: Option<f64>,
    /// Read noise, electrons rms.
    pub read_noise_e: Option<f64>,
    /// Fixed-pattern gain (photo-response non-uniformity), fraction rms.
    pub prnu: Option<f64>,
    /// Fixed-pattern offset (dark-signal non-uniformity), electrons rms.
    pub dsnu_e: Option<f64>,
    /// Grey levels per full well, as a fraction of 255.
    pub gain: Option<f64>,
    pub black_level_dn: Option<f64>,
    /// Response curve: grey level grows as `signal^gamma`.
    pub gamma: Option<f64>,
}

/// A camera's sensor as used.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, Deserialize)]
pub struct Sensor {
    pub full_well_e: f64,
    pub white_e: f64,
    pub read_noise_e: f64,
    pub prnu: f64,
    pub dsnu_e: f64,
    pub gain: f64,
    pub black_level_dn: f64,
    pub gamma: f64,
}

impl Sensor {
    /// The default sensor of the left or right camera.
    pub fn default_for(side: Side) -> Sensor {
        Sensor::resolve(&SensorSpec::default(), side)
    }

    fn resolve(spec: &SensorSpec, side: Side) -> Sensor {
        let (gain, black, gamma) = match side {
            Side::Left => (1.0, 6.0, 0.97),
            Side::Right => (1.05, 9.0, 0.94),
        };
        Sensor {
            full_well_e: spec.full_well_e.unwrap_or(18_000.0),
            white_e: spec.white_e.unwrap_or(15_000.0),
            read_noise_e: spec.read_noise_e.unwrap_or(15.0),
            prnu: spec.prnu.unwrap_or(0.01),
            dsnu_e: spec.dsnu_e.unwrap_or(20.0),
            gain: spec.gain.unwrap_or(gain),
            black_level_dn: spec.black_level_dn.unwrap_or(black),
            gamma: spec.gamma.unwrap_or(gamma),
        }
    }

    /// The mean grey level (before quantisation) of `electrons` collected.
    pub fn grey_level(&self, electrons: f64) -> f64 {
        let signal = (electrons / self.full_well_e).clamp(0.0, 1.0);
        self.black_level_dn + 255.0 * self.gain * signal.powf(self.gamma)
    }
}

/// How far a camera stands off its nominal pose. Left out: drawn from `as_built_seed`, a
/// Gaussian of `position_sigma_mm` along each axis and `rotation_sigma_deg` about each.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MountingSpec {
    /// The offset itself, in the camera's own frame, millimetres (overrides the draw).
    pub offset_mm: Option<[f64; 3]>,
    /// The turn itself, about the camera's own x, y, z, degrees (overrides the draw).
    pub rotation_deg: Option<[f64; 3]>,
    pub position_sigma_mm: Option<f64>,
    pub rotation_sigma_deg: Option<f64>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    Left,
    Right,
}

/// One camera as built: where it truly stands, its lens and its sensor.
#[derive(Debug, Clone, PartialEq, serde::Serialize, Deserialize)]
pub struct CameraAsBuilt {
    /// The true pinhole: the nominal intrinsics at the true mounting.
    pub pinhole: PinholeCamera,
    /// `nominal_cam_from_true_cam`: how the mounting moved the camera, in its nominal frame.
    #[serde(with = "mesh::pose::iso_serde")]
    pub nominal_from_true: Isometry3<f64>,
    pub lens: Lens,
    pub sensor: Sensor,
    /// Width of a pixel, millimetres (`focal_length_mm / focal_px`).
    pub pixel_pitch_mm: f64,
    /// Seed of this sensor's fixed patterns.
    pub pattern_seed: u64,
}

/// Both cameras as built.
#[derive(Debug, Clone, PartialEq, serde::Serialize, Deserialize)]
pub struct RigAsBuilt {
    pub left: CameraAsBuilt,
    pub right: CameraAsBuilt,
}

/// What the world file says of one camera beyond its nominal pinhole.
#[derive(Debug, Clone, Copy)]
pub struct CameraSpecs<'a> {
    pub nominal: &'a PinholeCamera,
    pub lens: Option<&'a LensSpec>,
    pub sensor: Option<&'a SensorSpec>,
    pub mounting: Option<&'a MountingSpec>,
}

impl RigAsBuilt {
    /// Both cameras as built from their specs, the mounting errors drawn from `as_built_seed`.
    pub fn new(left: CameraSpecs, right: CameraSpecs, effects: &Effects, as_built_seed: u64) -> RigAsBuilt {
        let mut rng = StdRng::seed_from_u64(as_built_seed.wrapping_mul(0x5851_F42D_4C95_7F2D).wrapping_add(17));
        let left = CameraAsBuilt::new(left, Side::Left, effects, &mut rng, as_built_seed.wrapping_mul(2));
        let right =
            CameraAsBuilt::new(right, Side::Right, effects, &mut rng, as_built_seed.wrapping_mul(2).wrapping_add(1));
        RigAsBuilt { left, right }
    }

    pub fn calibration(&self) -> mesh::StereoCalibration {
        mesh::StereoCalibration { left: self.left.pinhole.clone(), right: self.right.pinhole.clone() }
    }
}

impl CameraAsBuilt {
    /// The true camera: its pinhole at the true mounting, with its lens's distortion.
    pub fn lens_camera(&self) -> mesh::LensCamera {
        mesh::LensCamera { pinhole: self.pinhole.clone(), distortion: self.lens.distortion }
    }

    fn new(spec: CameraSpecs, side: Side, effects: &Effects, rng: &mut StdRng, pattern_seed: u64) -> CameraAsBuilt {
        let nominal = spec.nominal.clone();
        let m = spec.mounting.cloned().unwrap_or_default();
        // Both draws are made whether or not they are used, so switching one effect leaves the
        // other draws as they were.
        let gauss = |rng: &mut StdRng, sigma: f64| Normal::new(0.0, sigma).expect("sigma is checked").sample(rng);
        let (ps, rs) = (m.position_sigma_mm.unwrap_or(2.0), m.rotation_sigma_deg.unwrap_or(0.15));
        let drawn_offset = [gauss(rng, ps), gauss(rng, ps), gauss(rng, ps)];
        let drawn_turn = [gauss(rng, rs), gauss(rng, rs), gauss(rng, rs)];
        let nominal_from_true = if effects.mounting {
            let [x, y, z] = m.offset_mm.unwrap_or(drawn_offset).map(|v| v * 1e-3);
            let [a, b, c] = m.rotation_deg.unwrap_or(drawn_turn).map(f64::to_radians);
            Isometry3::from_parts(Translation3::new(x, y, z), UnitQuaternion::from_euler_angles(a, b, c))
        } else {
            Isometry3::identity()
        };
        let pinhole = PinholeCamera { world_from_cam: nominal.world_from_cam * nominal_from_true, ..nominal };
        let mut lens = Lens::resolve(&spec.lens.cloned().unwrap_or_default(), side);
        if !effects.distortion {
            lens.distortion = PlumbBob::default();
        }
        let sensor = Sensor::resolve(&spec.sensor.cloned().unwrap_or_default(), side);
        let pixel_pitch_mm = lens.focal_length_mm / nominal.fx;
        CameraAsBuilt { pinhole, nominal_from_true, lens, sensor, pixel_pitch_mm, pattern_seed }
    }
}

/// A lamp: a glowing disc facing the middle of the table.
#[derive(Debug, Clone, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct LampSpec {
    pub position_m: [f64; 3],
    /// Radius of the glowing disc: the larger, the softer the shadows.
    #[serde(default = "default_lamp_radius")]
    pub radius_m: f64,
    /// Irradiance (fraction of full white) on a surface at the world origin facing the lamp; it
    /// falls off with the square of the distance elsewhere.
    pub irradiance: f64,
}

fn default_lamp_radius() -> f64 {
    0.1
}

/// Distance from the origin of the lamp that stands in for a world's distant `[light]` when it
/// lists no `[[lamps]]`.
pub const DEFAULT_LAMP_DISTANCE_M: f64 = 1.3;

impl LampSpec {
    /// The lamp in the `direction` of a world's distant light, as bright (`diffuse`) at the origin.
    pub fn from_light(direction: [f64; 3], diffuse: f64) -> LampSpec {
        let d = Vector3::from(direction).normalize() * DEFAULT_LAMP_DISTANCE_M;
        LampSpec { position_m: [d.x, d.y, d.z], radius_m: default_lamp_radius(), irradiance: diffuse }
    }

    pub fn position(&self) -> Point3<f64> {
        Point3::from(self.position_m)
    }
}

/// How a surface reflects, beyond its albedo.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Finish {
    /// Fraction of the light reflected glossily (the rest diffusely, times the albedo).
    pub specular: f32,
    /// Roughness of the gloss: 0 a mirror, 1 nearly diffuse.
    pub roughness: f32,
    /// Relative albedo variation of the table's texture (0: none).
    pub texture: f32,
    /// This instance's albedo as a multiple of its model's.
    pub albedo_scale: f32,
}

impl Finish {
    pub const MATTE: Finish = Finish { specular: 0.0, roughness: 1.0, texture: 0.0, albedo_scale: 1.0 };
}

/// The arm as built. Left out, each value is the default of a small arm of the UMI's class.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArmAsBuiltSpec {
    /// Spread of each joint's zero offset, degrees (metres x 1000 for a sliding joint).
    pub joint_offset_sigma_deg: Option<f64>,
    /// Spread of each link's length error along each axis of its joint's origin, millimetres.
    pub link_length_sigma_mm: Option<f64>,
    /// Counts per turn of a revolute joint's encoder.
    pub encoder_counts_per_rev: Option<f64>,
    /// Counts per metre of a sliding joint's encoder.
    pub encoder_counts_per_m: Option<f64>,
}

/// The arm as built: each arm joint's zero offset (the encoder reads `q` where the drawing's
/// joint stands at `q + offset`), each joint origin's position error (link lengths off), and
/// the encoders' resolution. The simulated arm moves as built; the robot server knows only the
/// URDF and the encoder readings.
#[derive(Debug, Clone, PartialEq, serde::Serialize, Deserialize)]
pub struct ArmAsBuilt {
    /// Per arm joint (`robot::arm::ARM_JOINTS` order): radians, or metres for a sliding joint.
    pub joint_offsets: [f64; 6],
    /// Per arm joint: the shift of its origin in its parent link, metres.
    pub origin_errors_m: [[f64; 3]; 6],
    pub encoder_counts_per_rev: f64,
    pub encoder_counts_per_m: f64,
}

impl ArmAsBuilt {
    /// The arm of `as_built_seed` (`None` with the effect off).
    pub fn new(spec: Option<&ArmAsBuiltSpec>, effects: &Effects, as_built_seed: u64) -> Option<ArmAsBuilt> {
        if !effects.arm_as_built {
            return None;
        }
        let spec = spec.cloned().unwrap_or_default();
        let mut rng = StdRng::seed_from_u64(as_built_seed.wrapping_mul(0xA076_1D64_78BD_642F).wrapping_add(29));
        let angle = Normal::new(0.0, spec.joint_offset_sigma_deg.unwrap_or(0.1)).expect("sigma is checked");
        let length = Normal::new(0.0, spec.link_length_sigma_mm.unwrap_or(0.2)).expect("sigma is checked");
        // The first joint (`zed`) slides: its offset in millimetres as the others' in degrees.
        let joint_offsets = std::array::from_fn(|k| {
            let v = angle.sample(&mut rng);
            if k == 0 { v * 1e-3 } else { v.to_radians() }
        });
        let origin_errors_m = std::array::from_fn(|_| std::array::from_fn(|_| length.sample(&mut rng) * 1e-3));
        Some(ArmAsBuilt {
            joint_offsets,
            origin_errors_m,
            encoder_counts_per_rev: spec.encoder_counts_per_rev.unwrap_or(16384.0),
            encoder_counts_per_m: spec.encoder_counts_per_m.unwrap_or(1e5),
        })
    }

    /// The URDF as built: each arm joint `j` of the drawing, `parent_from_child(q) = O M(q)`,
    /// becomes `T(e_j) O M(offset_j)`, so the joint at `q` stands where the drawing's would at
    /// `q + offset_j`, its origin shifted by `e_j`.
    pub fn apply(&self, robot: &mut urdf_rs::Robot) -> Result<(), String> {
        for (k, name) in robot::arm::ARM_JOINTS.iter().enumerate() {
            let joint = robot.joints.iter_mut().find(|j| j.name == *name).ok_or(format!("no joint `{name}`"))?;
            let axis = Vector3::from(joint.axis.xyz.0);
            let motion = match joint.joint_type {
                urdf_rs::JointType::Prismatic => Isometry3::translation(
                    axis.x * self.joint_offsets[k],
                    axis.y * self.joint_offsets[k],
                    axis.z * self.joint_offsets[k],
                ),
                _ => Isometry3::rotation(axis.normalize() * self.joint_offsets[k]),
            };
            let [x, y, z] = self.origin_errors_m[k];
            let origin = Isometry3::translation(x, y, z) * robot::arm::origin_pose(&joint.origin) * motion;
            let (roll, pitch, yaw) = origin.rotation.euler_angles();
            let t = origin.translation.vector;
            joint.origin =
                urdf_rs::Pose { xyz: urdf_rs::Vec3([t.x, t.y, t.z]), rpy: urdf_rs::Vec3([roll, pitch, yaw]) };
        }
        Ok(())
    }

    /// The URDF file at `path` as built, as URDF text.
    pub fn urdf_text(&self, path: &std::path::Path) -> Result<String, String> {
        let text = std::fs::read_to_string(path).map_err(|e| e.to_string())?;
        let mut drawn = urdf_rs::read_from_string(&text).map_err(|e| e.to_string())?;
        self.apply(&mut drawn)?;
        urdf_rs::write_to_string(&drawn).map_err(|e| e.to_string())
    }

    /// What arm joint `k`'s encoder reads when the joint stands at `q`: `q` to the nearest count.
    pub fn read_encoder(&self, k: usize, q: f64) -> f64 {
        let step =
            if k == 0 { 1.0 / self.encoder_counts_per_m } else { std::f64::consts::TAU / self.encoder_counts_per_rev };
        (q / step).round() * step
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_switch_every_effect_and_each_can_be_set_alone() {
        let all = Effects::resolve(Preset::Realistic, &EffectsSpec::default());
        assert!(all.distortion && all.shadows && all.arm_as_built && all.any_imaging());
        let none = Effects::resolve(Preset::Ideal, &EffectsSpec::default());
        assert!(!none.any_imaging() && !none.mounting && !none.arm_as_built);
        let blur_only = Effects::resolve(Preset::Ideal, &EffectsSpec { blur: Some(true), ..Default::default() });
        assert!(blur_only.blur && !blur_only.distortion && blur_only.any_imaging());
    }

    #[test]
    fn defocus_vanishes_at_the_focused_depth_and_grows_away_from_it() {
        let lens = Lens::resolve(&LensSpec::default(), Side::Left);
        assert_eq!(lens.circle_of_confusion_px(0.9, 0.008), 0.0);
        let (near, far) = (lens.circle_of_confusion_px(0.7, 0.008), lens.circle_of_confusion_px(1.3, 0.008));
        // By hand: A = 4 mm; at 0.7 m, 4 x 8 x 200 / (700 x 892) mm = 0.01025 mm = 1.28 px.
        assert!((near - 1.2811).abs() < 1e-3, "{near}");
        assert!(far > 1.0 && lens.blur_sigma_px(0.9, 0.008) == lens.psf_sigma_px);
    }
}
