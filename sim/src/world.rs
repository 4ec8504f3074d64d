//! World files, `worlds/*.toml`: the table, the light, the stereo rig, the objects (placed or
//! dropped as clutter), the robot's place and the bins. Units are metres and degrees.
//!
//! A malformed file is rejected with a [`WorldError`] naming the file, the line and the field.

use crate::realism::{ArmAsBuiltSpec, Effects, EffectsSpec, LampSpec, LensSpec, MountingSpec, Preset, SensorSpec};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// A scenario, as written in `worlds/*.toml`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WorldFile {
    #[serde(default)]
    pub name: String,
    /// The seed of every random choice (clutter poses, sensor noise); `--seed` overrides it.
    #[serde(default)]
    pub seed: u64,
    /// How real the cell is: `"realistic"` (the default) or `"ideal"` (the first simulation's
    /// cell, its images bit for bit); see [`crate::realism`].
    #[serde(default)]
    pub realism: Preset,
    /// Each effect switched on its own, over the preset.
    #[serde(default)]
    pub effects: EffectsSpec,
    /// Seed of the cell as built (camera mounting, sensors' fixed patterns, the arm's offsets):
    /// the same cell whatever the scene's seed.
    #[serde(default = "one_u64")]
    pub as_built_seed: u64,
    /// Lamps of the realistic cell; absent, one lamp in the direction of `[light]`.
    pub lamps: Option<Vec<LampSpec>>,
    /// Folder of model files, relative to the world file; the project's `mesh/models` if absent.
    pub library: Option<PathBuf>,
    pub table: TableSpec,
    #[serde(default)]
    pub light: LightSpec,
    pub cameras: RigSpec,
    #[serde(default)]
    pub render: RenderSpec,
    #[serde(default)]
    pub physics: PhysicsSpec,
    /// Objects placed at given poses (they still settle under gravity).
    #[serde(default)]
    pub objects: Vec<PlacedObject>,
    /// Objects dropped at random poses over a region.
    pub clutter: Option<ClutterSpec>,
    /// Where the arm stands (the arm itself is built by the robot work).
    pub robot: Option<RobotSpec>,
    /// Place targets.
    #[serde(default)]
    pub bins: Vec<BinSpec>,
}

/// The table: its top is the `world` frame's `z = 0` plane, centred on the origin.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TableSpec {
    pub size_m: [f64; 2],
    pub height_m: f64,
    pub albedo: f64,
    #[serde(default = "default_floor_albedo")]
    pub floor_albedo: f64,
    /// Relative albedo variation of the top's faint texture (realistic preset).
    #[serde(default = "default_table_texture")]
    pub texture: f64,
}

fn default_table_texture() -> f64 {
    0.06
}

fn one_u64() -> u64 {
    1
}

fn default_floor_albedo() -> f64 {
    0.15
}

/// One directional light plus ambient light; intensities as fractions of full white.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightSpec {
    /// Direction from the scene towards the light (need not be unit length).
    pub direction: [f64; 3],
    pub diffuse: f64,
    pub ambient: f64,
}

impl Default for LightSpec {
    fn default() -> Self {
        LightSpec { direction: [-0.3, -0.5, 1.0], diffuse: 0.75, ambient: 0.25 }
    }
}

/// The two cameras. They verge on the workspace: the pipeline must rectify.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigSpec {
    pub left: CameraSpec,
    pub right: CameraSpec,
}

/// A pinhole camera given by where it is and what it looks at.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraSpec {
    #[serde(default = "default_resolution")]
    pub resolution: [u32; 2],
    pub focal_px: f64,
    /// Defaults to the image centre, `((w - 1) / 2, (h - 1) / 2)`.
    pub principal_point: Option<[f64; 2]>,
    pub position_m: [f64; 3],
    pub look_at_m: [f64; 3],
    #[serde(default = "default_up")]
    pub up: [f64; 3],
    /// The lens (realistic preset); each value has a default.
    pub lens: Option<LensSpec>,
    /// The sensor (realistic preset); each value has a default.
    pub sensor: Option<SensorSpec>,
    /// How far the camera is mounted off this pose (realistic preset).
    pub mounting: Option<MountingSpec>,
}

fn default_resolution() -> [u32; 2] {
    [512, 512]
}

fn default_up() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

/// Rendering options.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderSpec {
    /// Standard deviation of the Gaussian sensor noise, grey levels.
    pub noise_sigma: f64,
}

impl Default for RenderSpec {
    fn default() -> Self {
        RenderSpec { noise_sigma: 1.5 }
    }
}

/// Simulation options.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PhysicsSpec {
    pub timestep_s: f64,
    /// Settling stops when everything is at rest or after this much simulated time.
    pub settle_limit_s: f64,
    pub friction: f64,
}

impl Default for PhysicsSpec {
    fn default() -> Self {
        PhysicsSpec { timestep_s: 1.0 / 240.0, settle_limit_s: 8.0, friction: 0.7 }
    }
}

/// An object at a given pose.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlacedObject {
    pub model: String,
    pub position_m: [f64; 3],
    #[serde(default)]
    pub rpy_deg: [f64; 3],
}

/// Objects dropped from random poses above a region of the table.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClutterSpec {
    pub objects: Vec<ClutterItem>,
    pub region_m: RegionSpec,
    /// Range of heights of the drop poses above the table.
    #[serde(default = "default_drop_height")]
    pub drop_height_m: [f64; 2],
}

fn default_drop_height() -> [f64; 2] {
    [0.06, 0.3]
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClutterItem {
    pub model: String,
    #[serde(default = "one")]
    pub count: u32,
}

fn one() -> u32 {
    1
}

/// An axis-aligned rectangle on the table.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RegionSpec {
    pub min: [f64; 2],
    pub max: [f64; 2],
}

/// The arm's base; the URDF is read by the robot work.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotSpec {
    pub urdf: PathBuf,
    pub base_position_m: [f64; 3],
    #[serde(default)]
    pub base_yaw_deg: f64,
    /// The arm as built (realistic preset); each value has a default.
    pub as_built: Option<ArmAsBuiltSpec>,
}

impl RobotSpec {
    /// Where the arm's base stands: `world_from_base`.
    pub fn world_from_base(&self) -> nalgebra::Isometry3<f64> {
        let [x, y, z] = self.base_position_m;
        nalgebra::Isometry3::from_parts(
            nalgebra::Translation3::new(x, y, z),
            nalgebra::UnitQuaternion::from_axis_angle(&nalgebra::Vector3::z_axis(), self.base_yaw_deg.to_radians()),
        )
    }
}

/// An open box standing on the table.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BinSpec {
    pub name: String,
    /// Centre of the bin's floor on the table.
    pub centre_m: [f64; 2],
    /// Inside length, width and wall height.
    pub size_m: [f64; 3],
    #[serde(default = "default_wall")]
    pub wall_m: f64,
    #[serde(default = "default_bin_albedo")]
    pub albedo: f64,
}

fn default_wall() -> f64 {
    0.005
}

fn default_bin_albedo() -> f64 {
    0.5
}

/// A world file that cannot be used, with where and why.
#[derive(Debug, thiserror::Error)]
pub enum WorldError {
    #[error("{file}: {cause}")]
    Io { file: String, cause: std::io::Error },
    #[error("{file}:{line}: field `{field}`: {message}")]
    Invalid { file: String, line: usize, field: String, message: String },
}

impl WorldFile {
    /// The effects in force: the preset's, with `[effects]` over them.
    pub fn effects(&self) -> Effects {
        Effects::resolve(self.realism, &self.effects)
    }

    /// Reads and checks a world file.
    pub fn load(path: &Path) -> Result<WorldFile, WorldError> {
        let text = std::fs::read_to_string(path)
            .map_err(|cause| WorldError::Io { file: path.display().to_string(), cause })?;
        Self::parse(&text, &path.display().to_string())
    }

    /// Parses and checks world-file text; `file` names it in errors.
    pub fn parse(text: &str, file: &str) -> Result<WorldFile, WorldError> {
        let invalid = |line: usize, field: String, message: String| WorldError::Invalid {
            file: file.to_string(),
            line,
            field,
            message,
        };
        let de = toml::Deserializer::parse(text)
            .map_err(|e| invalid(line_at(text, e.span()), String::new(), e.message().to_string()))?;
        let world: WorldFile = serde_path_to_error::deserialize(de).map_err(|e| {
            let field = e.path().to_string();
            let inner = e.into_inner();
            invalid(line_at(text, inner.span()), field, inner.message().to_string())
        })?;
        let at_fault = |(field, message): (String, String)| invalid(line_of_field(text, &field), field, message);
        first_non_finite(text).map_or(Ok(()), |field| {
            Err(at_fault((field, "must be a finite number (nan and inf have no place in a world)".into())))
        })?;
        world.check().map_err(at_fault)?;
        Ok(world)
    }

    /// Checks what the types cannot: ranges and consistency. Returns the field at fault.
    fn check(&self) -> Result<(), (String, String)> {
        self.check_table_and_light()?;
        self.check_cameras()?;
        self.check_realism()?;
        self.check_render_and_physics()?;
        self.check_clutter()?;
        self.check_bins()
    }

    fn check_table_and_light(&self) -> Result<(), (String, String)> {
        positive("table.size_m[0]", self.table.size_m[0])?;
        positive("table.size_m[1]", self.table.size_m[1])?;
        positive("table.height_m", self.table.height_m)?;
        fraction("table.albedo", self.table.albedo)?;
        fraction("table.floor_albedo", self.table.floor_albedo)?;
        if self.light.direction.iter().all(|c| *c == 0.0) {
            return Err(("light.direction".into(), "must not be zero".into()));
        }
        fraction("light.diffuse", self.light.diffuse)?;
        fraction("light.ambient", self.light.ambient)
    }

    fn check_cameras(&self) -> Result<(), (String, String)> {
        for (side, cam) in [("left", &self.cameras.left), ("right", &self.cameras.right)] {
            let field = |name: &str| format!("cameras.{side}.{name}");
            within(&field("focal_px"), cam.focal_px, 1.0, 1e6, "pixels")?;
            if cam.resolution.contains(&0) || cam.resolution.iter().any(|&r| r > 8192) {
                return Err((field("resolution"), format!("must be within 1-8192, got {:?}", cam.resolution)));
            }
            if let Some([u, v]) = cam.principal_point {
                let [w, h] = cam.resolution.map(f64::from);
                if !((0.0..=w).contains(&u) && (0.0..=h).contains(&v)) {
                    return Err((field("principal_point"), format!("must lie in the {w}x{h} image, got [{u}, {v}]")));
                }
            }
            let forward = sub(cam.look_at_m, cam.position_m);
            if norm(forward) < 1e-6 {
                return Err((field("look_at_m"), "must differ from position_m".into()));
            }
            if norm(cross(forward, cam.up)) < 1e-6 * norm(forward) * norm(cam.up) {
                return Err((
                    field("up"),
                    format!("{:?} is parallel to the view direction (or zero): no image 'up'", cam.up),
                ));
            }
        }
        let (l, r) = (&self.cameras.left, &self.cameras.right);
        if norm(sub(l.position_m, r.position_m)) < 1e-3 {
            return Err((
                "cameras.right.position_m".into(),
                "is within 1 mm of the left camera's: a stereo pair needs a baseline".into(),
            ));
        }
        if l.resolution != r.resolution {
            return Err((
                "cameras.right.resolution".into(),
                format!(
                    "{:?} differs from the left camera's {:?}: a stereo pair must match",
                    r.resolution, l.resolution
                ),
            ));
        }
        Ok(())
    }

    fn check_realism(&self) -> Result<(), (String, String)> {
        within("table.texture", self.table.texture, 0.0, 0.5, "")?;
        for (side, cam) in [("left", &self.cameras.left), ("right", &self.cameras.right)] {
            let field = |name: &str| format!("cameras.{side}.{name}");
            if let Some(l) = &cam.lens {
                if let Some(d) = l.distortion {
                    for (i, c) in d.iter().enumerate() {
                        within(&field(&format!("lens.distortion[{i}]")), *c, -2.0, 2.0, "")?;
                    }
                }
                let f = l.focal_length_mm.unwrap_or(8.0);
                within(&field("lens.focal_length_mm"), f, 0.5, 500.0, "mm")?;
                within(&field("lens.f_number"), l.f_number.unwrap_or(2.0), 0.5, 64.0, "")?;
                within(&field("lens.focus_distance_m"), l.focus_distance_m.unwrap_or(0.9), 2.0 * f * 1e-3, 1e3, "m")?;
                within(&field("lens.psf_sigma_px"), l.psf_sigma_px.unwrap_or(0.45), 0.0, 10.0, "pixels")?;
                within(&field("lens.vignetting_exponent"), l.vignetting_exponent.unwrap_or(4.0), 0.0, 20.0, "")?;
            }
            if let Some(s) = &cam.sensor {
                within(&field("sensor.full_well_e"), s.full_well_e.unwrap_or(18e3), 100.0, 1e7, "electrons")?;
                within(&field("sensor.white_e"), s.white_e.unwrap_or(15e3), 1.0, 1e7, "electrons")?;
                within(&field("sensor.read_noise_e"), s.read_noise_e.unwrap_or(15.0), 0.0, 1e4, "electrons")?;
                within(&field("sensor.prnu"), s.prnu.unwrap_or(0.01), 0.0, 0.5, "")?;
                within(&field("sensor.dsnu_e"), s.dsnu_e.unwrap_or(20.0), 0.0, 1e5, "electrons")?;
                within(&field("sensor.gain"), s.gain.unwrap_or(1.0), 0.01, 100.0, "")?;
                within(&field("sensor.black_level_dn"), s.black_level_dn.unwrap_or(6.0), 0.0, 128.0, "grey levels")?;
                within(&field("sensor.gamma"), s.gamma.unwrap_or(1.0), 0.2, 5.0, "")?;
            }
            if let Some(m) = &cam.mounting {
                within(&field("mounting.position_sigma_mm"), m.position_sigma_mm.unwrap_or(2.0), 0.0, 100.0, "mm")?;
                within(&field("mounting.rotation_sigma_deg"), m.rotation_sigma_deg.unwrap_or(0.15), 0.0, 10.0, "deg")?;
                for (i, v) in m.offset_mm.unwrap_or_default().iter().enumerate() {
                    within(&field(&format!("mounting.offset_mm[{i}]")), *v, -500.0, 500.0, "mm")?;
                }
                for (i, v) in m.rotation_deg.unwrap_or_default().iter().enumerate() {
                    within(&field(&format!("mounting.rotation_deg[{i}]")), *v, -45.0, 45.0, "deg")?;
                }
            }
        }
        for (i, lamp) in self.lamps.iter().flatten().enumerate() {
            if norm(lamp.position_m) < 0.05 {
                return Err((format!("lamps[{i}].position_m"), "must stand at least 5 cm from the origin".into()));
            }
            within(&format!("lamps[{i}].radius_m"), lamp.radius_m, 0.0, 2.0, "m")?;
            within(&format!("lamps[{i}].irradiance"), lamp.irradiance, 0.0, 10.0, "")?;
        }
        if let Some(a) = self.robot.as_ref().and_then(|r| r.as_built.as_ref()) {
            within("robot.as_built.joint_offset_sigma_deg", a.joint_offset_sigma_deg.unwrap_or(0.1), 0.0, 10.0, "deg")?;
            within("robot.as_built.link_length_sigma_mm", a.link_length_sigma_mm.unwrap_or(0.2), 0.0, 50.0, "mm")?;
            within(
                "robot.as_built.encoder_counts_per_rev",
                a.encoder_counts_per_rev.unwrap_or(16384.0),
                16.0,
                1e9,
                "",
            )?;
            within("robot.as_built.encoder_counts_per_m", a.encoder_counts_per_m.unwrap_or(1e5), 100.0, 1e12, "")?;
        }
        Ok(())
    }

    fn check_render_and_physics(&self) -> Result<(), (String, String)> {
        within("render.noise_sigma", self.render.noise_sigma, 0.0, 100.0, "grey levels")?;
        within("physics.timestep_s", self.physics.timestep_s, 1e-5, 0.05, "seconds")?;
        within("physics.settle_limit_s", self.physics.settle_limit_s, self.physics.timestep_s, 600.0, "seconds")?;
        within("physics.friction", self.physics.friction, 0.0, 10.0, "")
    }

    fn check_clutter(&self) -> Result<(), (String, String)> {
        let Some(c) = &self.clutter else { return Ok(()) };
        if c.objects.is_empty() {
            return Err(("clutter.objects".into(), "lists no objects".into()));
        }
        for (i, item) in c.objects.iter().enumerate() {
            if !(1..=MAX_CLUTTER_COUNT).contains(&item.count) {
                return Err((
                    format!("clutter.objects[{i}].count"),
                    format!(
                        "must be within 1-{MAX_CLUTTER_COUNT}, got {} (leave the entry out to drop none)",
                        item.count
                    ),
                ));
            }
        }
        let half = [self.table.size_m[0] / 2.0, self.table.size_m[1] / 2.0];
        for (i, half) in half.into_iter().enumerate() {
            if c.region_m.min[i] >= c.region_m.max[i] {
                return Err((format!("clutter.region_m.max[{i}]"), "must exceed min".into()));
            }
            for (end, v) in [("min", c.region_m.min[i]), ("max", c.region_m.max[i])] {
                if v.abs() > half {
                    return Err((
                        format!("clutter.region_m.{end}[{i}]"),
                        format!("{v} m lies off the table (its half-size is {half} m)"),
                    ));
                }
            }
        }
        if !(0.0 < c.drop_height_m[0] && c.drop_height_m[0] <= c.drop_height_m[1] && c.drop_height_m[1] <= 5.0) {
            return Err((
                "clutter.drop_height_m".into(),
                format!("must be 0 < low <= high <= 5 m, got {:?}", c.drop_height_m),
            ));
        }
        Ok(())
    }

    fn check_bins(&self) -> Result<(), (String, String)> {
        let half = [self.table.size_m[0] / 2.0, self.table.size_m[1] / 2.0];
        for (i, b) in self.bins.iter().enumerate() {
            for (k, s) in b.size_m.iter().enumerate() {
                positive(&format!("bins[{i}].size_m[{k}]"), *s)?;
            }
            positive(&format!("bins[{i}].wall_m"), b.wall_m)?;
            fraction(&format!("bins[{i}].albedo"), b.albedo)?;
            for (k, half) in half.into_iter().enumerate() {
                let reach = b.centre_m[k].abs() + b.size_m[k] / 2.0 + b.wall_m;
                if reach > half + 1e-9 {
                    return Err((
                        format!("bins[{i}].centre_m[{k}]"),
                        format!("puts the bin {reach:.3} m out, past the table's edge at {half} m"),
                    ));
                }
            }
            if self.bins[..i].iter().any(|other| other.name == b.name) {
                return Err((format!("bins[{i}].name"), format!("`{}` names two bins", b.name)));
            }
        }
        Ok(())
    }

    /// Checks that every model named exists in `library`.
    pub fn check_models(&self, library: &mesh::Library, text: &str, file: &str) -> Result<(), WorldError> {
        let named = self.objects.iter().enumerate().map(|(i, o)| (format!("objects[{i}].model"), &o.model));
        let clutter = self
            .clutter
            .iter()
            .flat_map(|c| c.objects.iter().enumerate().map(|(i, o)| (format!("clutter.objects[{i}].model"), &o.model)));
        for (field, model) in named.chain(clutter) {
            if library.get(model).is_none() {
                let known: Vec<&str> = library.names().collect();
                return Err(WorldError::Invalid {
                    file: file.to_string(),
                    line: line_of_field(text, &field),
                    message: format!("no model `{model}` in the library (it has: {})", known.join(", ")),
                    field,
                });
            }
        }
        Ok(())
    }

    /// The robot's URDF file, resolved against the world file's folder; an error names the
    /// `robot.urdf` line when the file is missing or is not a URDF the arm can be built from.
    pub fn robot_urdf(&self, world_path: &Path, text: &str) -> Result<Option<PathBuf>, WorldError> {
        let Some(robot) = &self.robot else { return Ok(None) };
        let path = world_path.parent().unwrap_or(Path::new(".")).join(&robot.urdf);
        let problem = match std::fs::read_to_string(&path) {
            Err(e) => Some(format!("cannot read {}: {e}", path.display())),
            Ok(urdf) => rapier3d_urdf::urdf_rs::read_from_string(&urdf)
                .err()
                .map(|e| format!("{} is not valid URDF: {e}", path.display())),
        };
        match problem {
            None => Ok(Some(path)),
            Some(message) => Err(WorldError::Invalid {
                file: world_path.display().to_string(),
                line: line_of_field(text, "robot.urdf"),
                field: "robot.urdf".into(),
                message,
            }),
        }
    }

    /// The model library this world uses.
    pub fn library_dir(&self, world_path: &Path) -> PathBuf {
        match &self.library {
            Some(dir) => world_path.parent().unwrap_or(Path::new(".")).join(dir),
            None => mesh::library::default_dir(),
        }
    }
}

/// Most objects one clutter entry may drop.
const MAX_CLUTTER_COUNT: u32 = 100;

fn positive(field: &str, v: f64) -> Result<(), (String, String)> {
    if v > 0.0 && v.is_finite() { Ok(()) } else { Err((field.to_string(), format!("must be positive, got {v}"))) }
}

fn fraction(field: &str, v: f64) -> Result<(), (String, String)> {
    within(field, v, 0.0, 1.0, "")
}

fn within(field: &str, v: f64, lo: f64, hi: f64, unit: &str) -> Result<(), (String, String)> {
    if (lo..=hi).contains(&v) {
        Ok(())
    } else {
        let unit = if unit.is_empty() { String::new() } else { format!(" {unit}") };
        Err((field.to_string(), format!("must be within {lo}-{hi}{unit}, got {v}")))
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

/// The first number in a TOML text that is `nan` or infinite, as a field path like
/// `cameras.left.position_m[1]`. No world field means anything non-finite, and the range checks
/// would let some through (every comparison with NaN is false).
fn first_non_finite(text: &str) -> Option<String> {
    fn walk(v: &toml::Value, path: String) -> Option<String> {
        match v {
            toml::Value::Float(f) if !f.is_finite() => Some(path),
            toml::Value::Table(t) => {
                t.iter().find_map(|(k, v)| walk(v, if path.is_empty() { k.clone() } else { format!("{path}.{k}") }))
            }
            toml::Value::Array(a) => a.iter().enumerate().find_map(|(i, v)| walk(v, format!("{path}[{i}]"))),
            _ => None,
        }
    }
    let table: toml::Table = toml::from_str(text).ok()?;
    walk(&toml::Value::Table(table), String::new())
}

/// 1-based line of a byte offset (line 1 when unknown).
fn line_at(text: &str, span: Option<std::ops::Range<usize>>) -> usize {
    span.map_or(1, |s| text[..s.start.min(text.len())].matches('\n').count() + 1)
}

/// 1-based line where a field like `bins[1].size_m[0]` is written; falls back to its nearest
/// written ancestor, then to line 1.
fn line_of_field(text: &str, field: &str) -> usize {
    let Ok(root) = toml::de::DeTable::parse(text) else {
        return 1;
    };
    let mut node: Option<&toml::Spanned<toml::de::DeValue>> = None;
    let mut span = None;
    for part in field.split('.') {
        let (key, indices) = part.split_at(part.find('[').unwrap_or(part.len()));
        let next = match node {
            None => root.get_ref().get(key),
            Some(n) => n.get_ref().get(key),
        };
        let Some(next) = next else { break };
        node = Some(next);
        span = Some(next.span());
        for index in indices.split(['[', ']']).filter(|s| !s.is_empty()) {
            let Some(next) = index.parse::<usize>().ok().and_then(|i| next_in(node, i)) else {
                break;
            };
            node = Some(next);
            span = Some(next.span());
        }
    }
    line_at(text, span)
}

fn next_in<'a, 'i>(
    node: Option<&'a toml::Spanned<toml::de::DeValue<'i>>>,
    i: usize,
) -> Option<&'a toml::Spanned<toml::de::DeValue<'i>>> {
    node?.get_ref().get(i)
}

#[cfg(test)]
mod tests;
