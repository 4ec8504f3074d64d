//! World files, `worlds/*.toml`: the table, the light, the stereo rig, the objects (placed or
//! dropped as clutter), the robot's place and the bins. Units are metres and degrees.
//!
//! A malformed file is rejected with a [`WorldError`] naming the file, the line and the field.

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
        world.check().map_err(|(field, message)| invalid(line_of_field(text, &field), field, message))?;
        Ok(world)
    }

    /// Checks what the types cannot: ranges and consistency. Returns the field at fault.
    fn check(&self) -> Result<(), (String, String)> {
        let positive = |field: &str, v: f64| {
            if v > 0.0 && v.is_finite() {
                Ok(())
            } else {
                Err((field.to_string(), format!("must be positive, got {v}")))
            }
        };
        let unit = |field: &str, v: f64| {
            if (0.0..=1.0).contains(&v) {
                Ok(())
            } else {
                Err((field.to_string(), format!("must be within 0-1, got {v}")))
            }
        };
        positive("table.size_m[0]", self.table.size_m[0])?;
        positive("table.size_m[1]", self.table.size_m[1])?;
        positive("table.height_m", self.table.height_m)?;
        unit("table.albedo", self.table.albedo)?;
        unit("table.floor_albedo", self.table.floor_albedo)?;
        if self.light.direction.iter().all(|c| *c == 0.0) {
            return Err(("light.direction".into(), "must not be zero".into()));
        }
        for (side, cam) in [("left", &self.cameras.left), ("right", &self.cameras.right)] {
            positive(&format!("cameras.{side}.focal_px"), cam.focal_px)?;
            if cam.resolution.contains(&0) || cam.resolution.iter().any(|&r| r > 8192) {
                return Err((
                    format!("cameras.{side}.resolution"),
                    format!("must be within 1-8192, got {:?}", cam.resolution),
                ));
            }
            let to_target: f64 = (0..3).map(|i| (cam.look_at_m[i] - cam.position_m[i]).powi(2)).sum();
            if to_target < 1e-12 {
                return Err((format!("cameras.{side}.look_at_m"), "must differ from position_m".into()));
            }
        }
        if !(self.render.noise_sigma.is_finite() && self.render.noise_sigma >= 0.0) {
            return Err(("render.noise_sigma".into(), format!("must be >= 0, got {}", self.render.noise_sigma)));
        }
        positive("physics.timestep_s", self.physics.timestep_s)?;
        positive("physics.settle_limit_s", self.physics.settle_limit_s)?;
        if let Some(c) = &self.clutter {
            if c.objects.is_empty() {
                return Err(("clutter.objects".into(), "lists no objects".into()));
            }
            for i in 0..2 {
                if c.region_m.min[i] >= c.region_m.max[i] {
                    return Err((format!("clutter.region_m.max[{i}]"), "must exceed min".into()));
                }
            }
            if !(0.0 < c.drop_height_m[0] && c.drop_height_m[0] <= c.drop_height_m[1]) {
                return Err((
                    "clutter.drop_height_m".into(),
                    format!("must be 0 < low <= high, got {:?}", c.drop_height_m),
                ));
            }
        }
        for (i, b) in self.bins.iter().enumerate() {
            for (k, s) in b.size_m.iter().enumerate() {
                positive(&format!("bins[{i}].size_m[{k}]"), *s)?;
            }
            positive(&format!("bins[{i}].wall_m"), b.wall_m)?;
            unit(&format!("bins[{i}].albedo"), b.albedo)?;
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
mod tests {
    use super::*;

    const GOOD: &str = r#"
seed = 3
[table]
size_m = [1.0, 1.0]
height_m = 0.7
albedo = 0.3
[cameras.left]
focal_px = 900.0
position_m = [-0.1, -0.7, 0.6]
look_at_m = [0.0, 0.0, 0.0]
[cameras.right]
focal_px = 900.0
position_m = [0.1, -0.7, 0.6]
look_at_m = [0.0, 0.0, 0.0]
[[objects]]
model = "block"
position_m = [0.0, 0.0, 0.015]
"#;

    fn error_of(text: &str) -> (usize, String, String) {
        match WorldFile::parse(text, "w.toml") {
            Err(WorldError::Invalid { line, field, message, .. }) => (line, field, message),
            other => panic!("expected an invalid-world error, got {other:?}"),
        }
    }

    #[test]
    fn a_good_file_parses_with_defaults() {
        let w = WorldFile::parse(GOOD, "w.toml").unwrap();
        assert_eq!(w.seed, 3);
        assert_eq!(w.cameras.left.resolution, [512, 512]);
        assert_eq!(w.render.noise_sigma, 1.5);
    }

    #[test]
    fn a_wrong_type_names_its_line_and_field() {
        let bad = GOOD.replace("focal_px = 900.0\nposition_m = [0.1", "focal_px = \"wide\"\nposition_m = [0.1");
        let (line, field, message) = error_of(&bad);
        assert_eq!(line, 12);
        assert_eq!(field, "cameras.right.focal_px");
        assert!(message.contains("expected f64"), "{message}");
    }

    #[test]
    fn an_unknown_field_is_named() {
        let bad = GOOD.replace("albedo = 0.3", "albedo = 0.3\ncolour = 2");
        let (line, field, message) = error_of(&bad);
        assert_eq!(line, 7);
        assert_eq!(field, "table.colour");
        assert!(message.contains("unknown field `colour`"), "{message}");
    }

    #[test]
    fn a_missing_field_is_named() {
        let bad = GOOD.replace("height_m = 0.7\n", "");
        let (_, field, message) = error_of(&bad);
        assert_eq!(field, "table");
        assert!(message.contains("missing field `height_m`"), "{message}");
    }

    #[test]
    fn a_syntax_error_names_its_line() {
        let bad = GOOD.replace("seed = 3", "seed = = 3");
        let (line, _, _) = error_of(&bad);
        assert_eq!(line, 2);
    }

    #[test]
    fn an_out_of_range_value_names_its_line_and_field() {
        let bad = GOOD.replace("focal_px = 900.0\nposition_m = [-0.1", "focal_px = -5.0\nposition_m = [-0.1");
        let (line, field, message) = error_of(&bad);
        assert_eq!((line, field.as_str()), (8, "cameras.left.focal_px"));
        assert!(message.contains("positive"), "{message}");
        let bad = GOOD.to_string() + "[[bins]]\nname = \"a\"\ncentre_m = [0.3, 0.0]\nsize_m = [0.2, 0.0, 0.05]\n";
        let (line, field, _) = error_of(&bad);
        assert_eq!((line, field.as_str()), (21, "bins[0].size_m[1]"));
    }

    #[test]
    fn an_unknown_model_names_its_line_and_field() {
        let bad = GOOD.replace("model = \"block\"", "model = \"teapot\"");
        let w = WorldFile::parse(&bad, "w.toml").unwrap();
        let lib = mesh::Library::load_default().unwrap();
        match w.check_models(&lib, &bad, "w.toml") {
            Err(WorldError::Invalid { line, field, message, .. }) => {
                assert_eq!((line, field.as_str()), (16, "objects[0].model"));
                assert!(message.contains("teapot") && message.contains("widget"), "{message}");
            }
            other => panic!("expected an error, got {other:?}"),
        }
    }
}
