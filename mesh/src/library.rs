//! The model library: every `*.toml` model file of a folder, built.

use crate::model::{Model, ModelSpec};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The environment variable that names the project's model folder where the binary runs
/// away from the checkout it was built in (a container, a cluster node).
pub const MODELS_ENV: &str = "MARVIN_MODELS";

/// Where the project's own model files live: `$MARVIN_MODELS` if it is set, else `mesh/models`
/// of the checkout the binary was built from.
pub fn default_dir() -> PathBuf {
    match std::env::var_os(MODELS_ENV) {
        Some(dir) if !dir.is_empty() => PathBuf::from(dir),
        _ => Path::new(env!("CARGO_MANIFEST_DIR")).join("models"),
    }
}

/// The models that are tools an operator hands to the arm for calibration, not parts: the
/// hand-eye flag and the camera calibration board. Scenes never hold them and the part search
/// never seeks them.
pub const TOOLS: [&str; 2] = ["board", "flag"];

/// Why a model folder could not be read, saying how to name the project's own elsewhere.
fn not_there(dir: &Path, e: std::io::Error) -> String {
    if dir == default_dir() && e.kind() == std::io::ErrorKind::NotFound {
        format!("{e}: the project's model folder is not here; set {MODELS_ENV} to it (mesh/models in the repository)")
    } else {
        e.to_string()
    }
}

/// Built models by name.
#[derive(Debug, Clone, Default)]
pub struct Library {
    pub models: BTreeMap<String, Model>,
}

/// Why a model file could not be used; names the file.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {message}")]
pub struct LibraryError {
    pub path: String,
    pub message: String,
}

impl Library {
    /// Loads and builds every model file in `dir`.
    pub fn load_dir(dir: &Path) -> Result<Library, LibraryError> {
        let err = |path: &Path, message: String| LibraryError { path: path.display().to_string(), message };
        let entries = std::fs::read_dir(dir).map_err(|e| err(dir, not_there(dir, e)))?;
        let mut files: Vec<PathBuf> = entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            .collect();
        files.sort();
        let mut lib = Library::default();
        for path in files {
            let model = Self::load_file(&path).map_err(|m| err(&path, m))?;
            if lib.models.contains_key(&model.name) {
                return Err(err(&path, format!("a second model named `{}`", model.name)));
            }
            lib.models.insert(model.name.clone(), model);
        }
        if lib.models.is_empty() {
            return Err(err(dir, "no model files (*.toml) found".into()));
        }
        Ok(lib)
    }

    /// The project's own library ([`default_dir`]).
    pub fn load_default() -> Result<Library, LibraryError> {
        Self::load_dir(&default_dir())
    }

    fn load_file(path: &Path) -> Result<Model, String> {
        let text = std::fs::read_to_string(path).map_err(|e| e.to_string())?;
        let spec: ModelSpec = toml::from_str(&text).map_err(|e| e.to_string())?;
        Model::build(&spec, path.parent().unwrap_or(Path::new(".")))
    }

    pub fn get(&self, name: &str) -> Option<&Model> {
        self.models.get(name)
    }

    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.models.keys().map(String::as_str)
    }

    /// The parts: every model but the [`TOOLS`].
    pub fn parts(&self) -> impl Iterator<Item = &Model> {
        self.models.values().filter(|m| !TOOLS.contains(&m.name.as_str()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Collision;
    use nalgebra::{Point3, Vector3};

    const LIBRARY: [&str; 9] =
        ["block", "board", "flag", "hex_prism", "l_bracket", "t_piece", "u_channel", "wedge", "widget"];

    /// Distances along the ray `o + t d` at which it crosses the mesh (Moller-Trumbore).
    fn crossings(mesh: &crate::TriMesh, o: Point3<f64>, d: Vector3<f64>) -> Vec<f64> {
        let mut ts: Vec<f64> =
            (0..mesh.triangles.len()).filter_map(|t| crate::trimesh::ray_triangle(&o, &d, &mesh.corners(t))).collect();
        ts.sort_by(f64::total_cmp);
        ts.dedup_by(|a, b| (*a - *b).abs() < 1e-9); // a ray through a shared edge hits twice
        ts
    }

    #[test]
    fn the_library_has_every_model_closed_and_sized() {
        let lib = Library::load_default().unwrap();
        assert_eq!(lib.names().collect::<Vec<_>>(), LIBRARY);
        for (name, m) in &lib.models {
            assert!(m.mesh.is_closed(), "{name} is not closed");
            let size = m.extent().max() * 1e3;
            let expected = match name.as_str() {
                "flag" => 40.0..=120.0,
                "board" => 160.0..=240.0,
                _ => 30.0..=120.0,
            };
            assert!(expected.contains(&size), "{name} is {size} mm across");
            assert!(m.mass.mass > 0.0 && m.mass.inertia.symmetric_eigenvalues().min() > 0.0);
            assert!(!m.grasps.is_empty(), "{name} has no grasp");
        }
    }

    #[test]
    fn the_widget_has_at_least_twelve_feature_edges() {
        let lib = Library::load_default().unwrap();
        assert_eq!(lib.get("widget").unwrap().wireframe.len(), 24);
        assert_eq!(lib.get("block").unwrap().wireframe.len(), 12);
        assert_eq!(lib.get("wedge").unwrap().wireframe.len(), 12);
        assert_eq!(lib.get("hex_prism").unwrap().wireframe.len(), 18);
    }

    #[test]
    fn grasp_openings_match_the_solid_between_the_jaws() {
        let lib = Library::load_default().unwrap();
        for (name, m) in &lib.models {
            for g in &m.grasps {
                let centre = g.model_from_gripper * Point3::origin();
                let jaw = g.model_from_gripper * Vector3::y();
                let start = centre - jaw * 1.0;
                let hits = crossings(&m.mesh, start, jaw);
                assert_eq!(hits.len(), 2, "{name}: the jaw line should cross the solid once");
                let width = hits[1] - hits[0];
                assert!((width - g.opening).abs() < 5e-4, "{name}: {width} m between jaws, file says {}", g.opening);
                assert!(hits[0] < 1.0 && 1.0 < hits[1], "{name}: the grasp centre is outside the solid");
            }
        }
    }

    #[test]
    fn exact_decompositions_cover_the_volume() {
        let lib = Library::load_default().unwrap();
        for (name, m) in &lib.models {
            let Collision::ConvexPieces(pieces) = &m.collision else { panic!("{name} is not exact") };
            // Each piece is a convex point set; its hull volume by the centroid fan of its faces is
            // awkward, so compare the summed profile areas times thickness for extrusions instead:
            // for any exact decomposition the mass of the pieces equals the mesh's.
            let total: f64 = pieces.iter().map(|p| hull_volume(p)).sum();
            assert!((total - m.mass.volume).abs() < 1e-9, "{name}: pieces {total} vs mesh {}", m.mass.volume);
        }
    }

    /// Volume of the convex hull of `pts` (a small brute force: every supporting triangle).
    fn hull_volume(pts: &[Point3<f64>]) -> f64 {
        let c = pts.iter().fold(Vector3::zeros(), |s, p| s + p.coords) / pts.len() as f64;
        let mut faces: Vec<Vector3<f64>> = Vec::new(); // unit normals of faces already counted
        let mut volume = 0.0;
        for i in 0..pts.len() {
            for j in i + 1..pts.len() {
                for k in j + 1..pts.len() {
                    let mut n = (pts[j] - pts[i]).cross(&(pts[k] - pts[i]));
                    if n.norm() < 1e-12 {
                        continue;
                    }
                    n.normalize_mut();
                    if n.dot(&(pts[i].coords - c)) < 0.0 {
                        n = -n;
                    }
                    let d = n.dot(&pts[i].coords);
                    if pts.iter().any(|p| n.dot(&p.coords) > d + 1e-12) || faces.iter().any(|f| (f - n).norm() < 1e-9) {
                        continue;
                    }
                    faces.push(n);
                    // Area of the face polygon: the points on its plane, ordered around their mean.
                    let on: Vec<Vector3<f64>> =
                        pts.iter().map(|p| p.coords).filter(|p| (n.dot(p) - d).abs() < 1e-12).collect();
                    let m = on.iter().sum::<Vector3<f64>>() / on.len() as f64;
                    let u = (on[0] - m).normalize();
                    let v = n.cross(&u);
                    let mut ring: Vec<(f64, Vector3<f64>)> =
                        on.iter().map(|p| ((p - m).dot(&v).atan2((p - m).dot(&u)), *p)).collect();
                    ring.sort_by(|a, b| a.0.total_cmp(&b.0));
                    let area: f64 = (0..ring.len())
                        .map(|q| (ring[q].1 - m).cross(&(ring[(q + 1) % ring.len()].1 - m)).dot(&n) / 2.0)
                        .sum();
                    volume += area * (d - n.dot(&c)) / 3.0;
                }
            }
        }
        volume
    }
}
