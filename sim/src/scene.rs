//! A scenario (world file + model library) turned into a settled scene: static boxes (floor,
//! table, bins) and objects at rest, with their ground-truth poses.

use crate::arm::{HOME, SimArm};
use crate::physics::{Cell, SettleReport, StaticBox};
use crate::world::{WorldError, WorldFile};
use mesh::{Library, TriMesh};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector4};
use rand::{RngExt, SeedableRng, rngs::StdRng};
use rand_distr::StandardNormal;
use std::path::{Path, PathBuf};

/// A world file with the library its models come from, checked against each other.
#[derive(Debug, Clone)]
pub struct Scenario {
    pub path: PathBuf,
    pub world: WorldFile,
    pub library: Library,
    /// The arm's URDF, when the world has a robot: it stands in the cell while objects settle.
    pub robot_urdf: Option<PathBuf>,
}

/// Why a scenario could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    #[error(transparent)]
    World(#[from] WorldError),
    #[error(transparent)]
    Library(#[from] mesh::library::LibraryError),
}

impl Scenario {
    pub fn load(path: &Path) -> Result<Scenario, ScenarioError> {
        let world = WorldFile::load(path)?;
        let library = Library::load_dir(&world.library_dir(path))?;
        let text = std::fs::read_to_string(path)
            .map_err(|cause| WorldError::Io { file: path.display().to_string(), cause })?;
        world.check_models(&library, &text, &path.display().to_string())?;
        let robot_urdf = world.robot_urdf(path, &text)?;
        Ok(Scenario { path: path.to_path_buf(), world, library, robot_urdf })
    }
}

/// Drops tried before a scene is accepted as it is.
const MAX_DROPS: u32 = 5;
/// Deepest interpenetration a settled scene may keep, metres.
const MAX_CONTACT_DEPTH: f64 = 0.75e-3;

/// The fixed boxes of a world: the floor, the table (top at `z = 0`) and each bin.
pub fn static_boxes(world: &WorldFile) -> Vec<StaticBox> {
    let t = &world.table;
    let (h, [sx, sy]) = (t.height_m, t.size_m);
    let mut boxes = vec![
        StaticBox::at("floor".into(), [0.0, 0.0, -h - 0.05], [10.0, 10.0, 0.05], t.floor_albedo),
        StaticBox::at("table".into(), [0.0, 0.0, -h / 2.0], [sx / 2.0, sy / 2.0, h / 2.0], t.albedo),
    ];
    for b in &world.bins {
        let ([cx, cy], [ix, iy, wall_h], w) = (b.centre_m, b.size_m, b.wall_m);
        let (ox, oy) = (ix / 2.0 + w, iy / 2.0 + w); // outer half sizes
        let z = w + wall_h / 2.0;
        let name = |part: &str| format!("bin {} {part}", b.name);
        boxes.extend([
            StaticBox::at(name("floor"), [cx, cy, w / 2.0], [ox, oy, w / 2.0], b.albedo),
            StaticBox::at(name("wall -x"), [cx - ox + w / 2.0, cy, z], [w / 2.0, oy, wall_h / 2.0], b.albedo),
            StaticBox::at(name("wall +x"), [cx + ox - w / 2.0, cy, z], [w / 2.0, oy, wall_h / 2.0], b.albedo),
            StaticBox::at(name("wall -y"), [cx, cy - oy + w / 2.0, z], [ix / 2.0, w / 2.0, wall_h / 2.0], b.albedo),
            StaticBox::at(name("wall +y"), [cx, cy + oy - w / 2.0, z], [ix / 2.0, w / 2.0, wall_h / 2.0], b.albedo),
        ]);
    }
    boxes
}

/// One object of a scene: `id` is 1-based and is what the id maps hold.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneObject {
    pub id: u32,
    pub model: String,
    pub world_from_model: Isometry3<f64>,
}

/// A settled scene with its ground truth.
#[derive(Debug, Clone)]
pub struct Scene {
    pub seed: u64,
    pub statics: Vec<StaticBox>,
    pub objects: Vec<SceneObject>,
    /// The arm's links where it stood (at home) while the scene settled, by URDF link name: the
    /// cameras see it too.
    pub arm: Vec<(String, TriMesh)>,
    pub settle: SettleReport,
}

impl Scene {
    /// Places the world's objects, drops its clutter from poses drawn with `seed`, and lets
    /// everything come to rest. Rapier occasionally leaves two compound objects wedged a
    /// millimetre or more into each other (about 2 drops in 100 of the default scene); such a
    /// drop is redone from poses drawn with a seed derived from `seed`, so the scene stays a
    /// function of the seed.
    pub fn settle(scn: &Scenario, seed: u64) -> Scene {
        let mut drop_seed = seed;
        for drops in 1..=MAX_DROPS {
            let mut scene = Self::drop_once(scn, seed, drop_seed);
            scene.settle.drops = drops;
            if scene.unsettled().is_none() || drops == MAX_DROPS {
                return scene;
            }
            drop_seed = drop_seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        }
        unreachable!("the last drop always returns")
    }

    /// Why the scene is not the settled scene it should be, if it is not: still moving when the
    /// settling time ran out, or two objects left wedged into each other, after every drop
    /// allowed. Such a scene is still used (it is a function of the seed), but whoever evaluates
    /// on it should say so.
    pub fn unsettled(&self) -> Option<String> {
        let s = &self.settle;
        if !s.at_rest {
            return Some(format!(
                "seed {}: not at rest after {:.1} s simulated ({} drops; fastest object {:.3} m/s, {:.2} rad/s)",
                self.seed, s.simulated_s, s.drops, s.max_linear_speed, s.max_angular_speed
            ));
        }
        (s.max_contact_depth > MAX_CONTACT_DEPTH).then(|| {
            format!(
                "seed {}: two objects left {:.2} mm into each other after {} drops (at most {:.2} mm allowed)",
                self.seed,
                s.max_contact_depth * 1e3,
                s.drops,
                MAX_CONTACT_DEPTH * 1e3
            )
        })
    }

    fn drop_once(scn: &Scenario, seed: u64, drop_seed: u64) -> Scene {
        let objects = initial_poses(scn, drop_seed);
        let statics = static_boxes(&scn.world);
        let mut cell = Cell::new(&scn.world.physics, &statics);
        let arm = scn.robot_urdf.as_ref().zip(scn.world.robot.as_ref()).map(|(urdf, spec)| {
            // Objects that roll up to the arm rest against it, not inside it.
            let built =
                crate::realism::ArmAsBuilt::new(spec.as_built.as_ref(), &scn.world.effects(), scn.world.as_built_seed);
            SimArm::insert(&mut cell, urdf, &spec.world_from_base(), &HOME, 0.0, built.as_ref())
                .expect("the URDF was checked on loading")
        });
        let bodies: Vec<_> =
            objects.iter().map(|o| cell.add_object(&scn.library.models[&o.model], &o.world_from_model)).collect();
        let settle = cell.settle(scn.world.physics.settle_limit_s);
        let objects = objects
            .into_iter()
            .zip(bodies)
            .map(|(o, body)| SceneObject { world_from_model: cell.pose(body), ..o })
            .collect();
        let arm = arm.map(|a| a.link_meshes(&cell)).unwrap_or_default();
        Scene { seed, statics, objects, arm, settle }
    }

    /// Every surface in world coordinates, tagged with its id-map value (0 for static parts,
    /// [`crate::render::arm_link_id`] for the arm's links).
    pub fn world_meshes<'a>(&'a self, library: &'a Library) -> impl Iterator<Item = (u32, TriMesh)> + 'a {
        let statics = self.statics.iter().map(|b| (0, b.mesh()));
        let objects =
            self.objects.iter().map(|o| (o.id, library.models[&o.model].mesh.transformed(&o.world_from_model)));
        let arm = self.arm.iter().enumerate().map(|(k, (_, m))| (crate::render::arm_link_id(k), m.clone()));
        statics.chain(objects).chain(arm)
    }

    /// The scene shaded for drawing by `imaging`: every surface with its finish (the parts'
    /// albedos varied by this scene's seed, with that effect on).
    pub fn render_scene(&self, library: &Library, imaging: &crate::imaging::Imaging) -> crate::render::RenderScene {
        let statics = self.statics.iter().map(|b| (0, b.mesh(), imaging.static_finish(b)));
        let objects = self.objects.iter().map(|o| {
            let model = &library.models[&o.model];
            (o.id, model.mesh.transformed(&o.world_from_model), imaging.object_finish(model, o.id, self.seed))
        });
        let arm = self
            .arm
            .iter()
            .enumerate()
            .map(|(k, (_, m))| (crate::render::arm_link_id(k), m.clone(), crate::imaging::ARM_FINISH));
        imaging.scene(statics.chain(objects).chain(arm))
    }
}

/// Drop poses: the placed objects as written, then clutter at random positions over the region
/// and random orientations, kept apart by their bounding spheres.
fn initial_poses(scn: &Scenario, seed: u64) -> Vec<SceneObject> {
    let mut out: Vec<SceneObject> = scn
        .world
        .objects
        .iter()
        .map(|o| (o.model.clone(), mesh::pose::from_position_rpy_deg(o.position_m, o.rpy_deg)))
        .enumerate()
        .map(|(i, (model, pose))| SceneObject { id: i as u32 + 1, model, world_from_model: pose })
        .collect();
    let Some(clutter) = &scn.world.clutter else {
        return out;
    };
    let mut rng = StdRng::seed_from_u64(seed);
    let mut spheres: Vec<(Point3<f64>, f64)> = out
        .iter()
        .map(|o| (o.world_from_model * Point3::origin(), scn.library.models[&o.model].mesh.radius()))
        .collect();
    let names = clutter.objects.iter().flat_map(|c| std::iter::repeat_n(&c.model, c.count as usize));
    for model in names {
        let radius = scn.library.models[model].mesh.radius();
        let (r, [lo, hi]) = (&clutter.region_m, clutter.drop_height_m);
        let mut centre = Point3::origin();
        for attempt in 0.. {
            // Every failed try raises the drop band, so a crowded drop always finds room.
            let lift = 0.02 * (attempt / 50) as f64;
            centre = Point3::new(
                rng.random_range(r.min[0]..=r.max[0]),
                rng.random_range(r.min[1]..=r.max[1]),
                rng.random_range(lo..=hi) + radius + lift,
            );
            if spheres.iter().all(|(c, rad)| (*c - centre).norm() > rad + radius) {
                break;
            }
        }
        spheres.push((centre, radius));
        let q: Vector4<f64> = Vector4::from_fn(|_, _| rng.sample(StandardNormal));
        let rotation = UnitQuaternion::from_quaternion(nalgebra::Quaternion::from(q));
        out.push(SceneObject {
            id: out.len() as u32 + 1,
            model: model.clone(),
            world_from_model: Isometry3::from_parts(Translation3::from(centre.coords), rotation),
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shipped_worlds_load() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds");
        let mut n = 0;
        let entries = std::fs::read_dir(&dir).unwrap().chain(std::fs::read_dir(dir.join("ideal")).unwrap());
        for entry in entries {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "toml") {
                Scenario::load(&path).unwrap_or_else(|e| panic!("{e}"));
                n += 1;
            }
        }
        assert!(n >= 8, "the shipped worlds and their ideal copies: {n}");
    }
}
