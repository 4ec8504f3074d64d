//! A pair's truth as `marvin render` writes it (scene.json, and `depth_left.png` beside it),
//! for `marvin locate --left --right --truth` and `marvin eval pairs`: reports judged after the
//! matcher has run, counted as `marvin eval locate` counts them.

use anyhow::{Context, bail};
use marvin::eval::truth::EvalCameras;
use marvin::eval::{LocateStats, locate_stats};
use nalgebra::Isometry3;
use sim::scene::SceneObject;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A scene's truth: each object's model and pose in the world, the cameras as built, and the
/// left camera's depth map where one lies beside the file.
pub struct SceneTruth {
    pub path: PathBuf,
    /// The seed `marvin render` drew the scene with, if the file says.
    pub seed: Option<u64>,
    objects: Vec<SceneObject>,
    /// Vision's frame is the true left camera's: measured cameras put their origin there.
    cams: EvalCameras,
    /// The left camera's depth (metres; no surface at infinity), to tell which objects are in
    /// view; `None` where `depth_left.png` is not beside the file.
    left_depth: Option<Vec<f32>>,
}

impl SceneTruth {
    pub fn load(path: &Path) -> anyhow::Result<SceneTruth> {
        let text = std::fs::read_to_string(path).with_context(|| format!("{}", path.display()))?;
        let scene: serde_json::Value =
            serde_json::from_str(&text).with_context(|| format!("{}: not JSON", path.display()))?;
        let objects = objects(&scene, path)?;
        let cams = cameras(&scene, path)?;
        let depth_path = path.with_file_name("depth_left.png");
        let left_depth = depth_path.exists().then(|| load_depth(&depth_path, &cams.true_left.pinhole)).transpose()?;
        Ok(SceneTruth { path: path.to_path_buf(), seed: scene["seed"].as_u64(), objects, cams, left_depth })
    }

    /// Object `index`'s pose in vision's frame (the true left camera's).
    pub fn cam_from_model(&self, index: usize) -> Isometry3<f64> {
        self.cams.vision.left.cam_from_world() * self.objects[index].world_from_model
    }

    /// The objects' ids in the id maps.
    pub fn id(&self, index: usize) -> u32 {
        self.objects[index].id
    }

    /// The reports judged as `marvin eval locate` judges them: each against the nearest object
    /// of its model not yet taken, correct within 10 mm and 5 deg; objects in view are those
    /// with 30% of their feature edges seen in the depth map (every object, without one).
    pub fn judge(&self, library: &mesh::Library, located: &[vision::matcher::Located]) -> LocateStats {
        let symmetry: BTreeMap<String, Vec<Isometry3<f64>>> =
            library.models.values().map(|m| (m.name.clone(), marvin::eval::symmetries(m))).collect();
        locate_stats(located, &self.objects, library, &self.cams, self.left_depth.as_deref(), &symmetry)
    }

    /// What became of the left edgels on the parts' edges (`eval vision`'s `left_edgels`,
    /// [`marvin::eval::edgel_fates`]), judged through `measured`, the cameras vision was given,
    /// placed where the true left camera stands. The truth is the parts and the table's top:
    /// an edgel counts where a ray a pixel either side of it, or through it, meets a part.
    pub fn part_edgel_fates(
        &self,
        library: &mesh::Library,
        fe: &vision::front_end::FrontEnd,
        measured: &mesh::StereoCalibration,
    ) -> BTreeMap<String, usize> {
        let parts: Vec<mesh::TriMesh> = self
            .objects
            .iter()
            .filter_map(|o| library.models.get(&o.model).map(|m| m.mesh.transformed(&o.world_from_model)))
            .collect();
        let part_triangles: usize = parts.iter().map(|m| m.triangles.len()).sum();
        let table = mesh::TriMesh::cuboid(nalgebra::Vector3::new(2.0, 2.0, 0.025), 0.3)
            .transformed(&Isometry3::translation(0.0, 0.0, -0.025));
        let truth = marvin::eval::truth::TruthScene::new(parts.into_iter().chain([table]));
        let cams = EvalCameras::measured_at(measured, self.cams.true_left.clone(), self.cams.true_right.clone());
        let on_part = |e: &vision::Edgel| {
            let (s, c) = (e.orientation as f64).sin_cos();
            [-1.0, 0.0, 1.0].iter().any(|k| {
                let (o, d) = cams.true_left.ray_world(e.x as f64 + k * c, e.y as f64 + k * s);
                truth.cast(&o, &d).is_some_and(|(_, t)| t < part_triangles)
            })
        };
        marvin::eval::edgel_fates(fe, &truth, &cams, &|e| !on_part(e))
    }

    pub fn has_depth(&self) -> bool {
        self.left_depth.is_some()
    }

    /// Each report against the nearest object of its model, taken or not: (id, mm, deg).
    pub fn nearest(
        &self,
        library: &mesh::Library,
        located: &[vision::matcher::Located],
    ) -> Vec<Option<(u32, f64, f64)>> {
        let cam_from_world = self.cams.vision.left.cam_from_world();
        located
            .iter()
            .map(|l| {
                let symmetries = library.get(&l.model).map(marvin::eval::symmetries).unwrap_or_default();
                self.objects
                    .iter()
                    .filter(|o| o.model == l.model)
                    .map(|o| {
                        let (m, rad) = marvin::eval::pose_error(
                            &l.cam_from_model,
                            &(cam_from_world * o.world_from_model),
                            &symmetries,
                        );
                        (o.id, m * 1e3, rad.to_degrees())
                    })
                    .min_by(|a, b| a.1.total_cmp(&b.1))
            })
            .collect()
    }
}

/// The `objects` list, each field read with its place named.
fn objects(scene: &serde_json::Value, path: &Path) -> anyhow::Result<Vec<SceneObject>> {
    let Some(list) = scene["objects"].as_array() else {
        bail!("{}: no `objects` list (a scene.json of `marvin render` has one)", path.display());
    };
    list.iter()
        .enumerate()
        .map(|(k, o)| {
            let model = o["model"].as_str().with_context(|| format!("{}: objects[{k}].model", path.display()))?;
            let pose: mesh::pose::PoseRecord = serde_json::from_value(o["world_from_model"].clone())
                .with_context(|| format!("{}: objects[{k}].world_from_model", path.display()))?;
            let id = o["id"].as_u64().unwrap_or(k as u64 + 1) as u32;
            Ok(SceneObject { id, model: model.to_string(), world_from_model: Isometry3::from(&pose) })
        })
        .collect()
}

/// The cameras as built (`as_built`), or, in a file without them, the calibration's pinholes.
fn cameras(scene: &serde_json::Value, path: &Path) -> anyhow::Result<EvalCameras> {
    if let Some(built) = scene.get("as_built") {
        let rig: sim::realism::RigAsBuilt =
            serde_json::from_value(built.clone()).with_context(|| format!("{}: field `as_built`", path.display()))?;
        let vision = mesh::StereoCalibration { left: rig.left.pinhole.clone(), right: rig.right.pinhole.clone() };
        return Ok(EvalCameras { vision, true_left: rig.left.lens_camera(), true_right: rig.right.lens_camera() });
    }
    let calibration: mesh::StereoCalibration = serde_json::from_value(scene["calibration"].clone())
        .with_context(|| format!("{}: field `calibration` (or `as_built`)", path.display()))?;
    Ok(EvalCameras {
        true_left: mesh::LensCamera::ideal(calibration.left.clone()),
        true_right: mesh::LensCamera::ideal(calibration.right.clone()),
        vision: calibration,
    })
}

/// A 16-bit depth map of `marvin render` (0.1 mm units, 0 for no surface) in metres.
fn load_depth(path: &Path, cam: &mesh::PinholeCamera) -> anyhow::Result<Vec<f32>> {
    let img = image::open(path).with_context(|| format!("{}: cannot read as an image", path.display()))?.into_luma16();
    if (img.width(), img.height()) != (cam.width, cam.height) {
        bail!("{}: {}x{}, but the camera is {}x{}", path.display(), img.width(), img.height(), cam.width, cam.height);
    }
    Ok(img
        .pixels()
        .map(|p| if p.0[0] == 0 { f32::INFINITY } else { (p.0[0] as f64 * sim::record::DEPTH_UNIT_M) as f32 })
        .collect())
}
