//! Occlusion in the image check: where a solid already located in front (or the model's own
//! bulk) hides part of a candidate's wireframe, that part can show no edgels, and counting it
//! as unseen rejects objects that are partly hidden. Solids are the models' triangles at their
//! located poses; a wireframe sample is hidden when the line of sight to it crosses one of them
//! well in front of it.

use super::model::MatcherModel;
use nalgebra::{Isometry3, Point3};

/// A model's surface at a pose, in the `cam` frame, with a sphere holding it.
pub struct Solid {
    triangles: Vec<[Point3<f64>; 3]>,
    centre: Point3<f64>,
    radius: f64,
}

/// An object judged on the part of its wireframe in view must have at least this share of its
/// camera-facing wireframe in view.
pub const MIN_IN_VIEW: f64 = 0.3;

/// A sample counts as hidden if a surface crosses its line of sight this far (metres) in front
/// of it: its own faces meet it at the edge itself.
const IN_FRONT_M: f64 = 0.002;

impl Solid {
    /// The model's solid at `pose` (`cam` frame). Only the triangles turned towards the camera
    /// are kept: a line of sight that crosses the closed surface (outward winding, as
    /// `MatcherModel` holds it) enters through one of them first, so the others never decide
    /// [`Solid::hides`], and testing them was half its work.
    pub fn new(model: &MatcherModel, pose: &Isometry3<f64>) -> Solid {
        let (centre, radius) = model.bounding_sphere();
        let facing = |t: &[Point3<f64>; 3]| (t[1] - t[0]).cross(&(t[2] - t[0])).dot(&t[0].coords) < 0.0;
        Solid {
            triangles: model.triangles.iter().map(|t| t.map(|p| pose * p)).filter(facing).collect(),
            centre: pose * centre,
            radius,
        }
    }

    /// Whether the solid may hide any of `other`, seen from a camera at the origin: their
    /// spheres' cones of sight overlap and part of this one lies nearer than all of the other.
    pub fn may_hide(&self, other: &Solid) -> bool {
        let (d, e) = (self.centre.coords.norm(), other.centre.coords.norm());
        if d <= self.radius || e <= other.radius {
            return true;
        }
        let apart = self.centre.coords.angle(&other.centre.coords);
        let reach = (self.radius / d).asin() + (other.radius / e).asin();
        apart < reach && d - self.radius < e + other.radius
    }

    /// Whether the solid hides point `x` (`cam` frame) from a camera at the origin.
    pub fn hides(&self, x: &Point3<f64>) -> bool {
        let eye = Point3::origin();
        let (d, dist) = (x.coords, x.coords.norm());
        // The line of sight must pass through the sphere, in front of the point.
        let along = self.centre.coords.dot(&d) / dist;
        if along - self.radius > dist - IN_FRONT_M || (d * (along / dist) - self.centre.coords).norm() > self.radius {
            return false;
        }
        let limit = 1.0 - IN_FRONT_M / dist;
        self.triangles.iter().filter_map(|t| mesh::trimesh::ray_triangle(&eye, &d, t)).any(|t| t > 0.0 && t < limit)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    /// A block 0.8 m in front of the camera hides what lies straight behind it, not what lies in
    /// front of it or beside it, nor its own edges facing the camera; the edges on its far side
    /// it does hide.
    #[test]
    fn a_block_hides_what_lies_behind_it() {
        let model = crate::matcher::fixtures::model("block");
        let pose =
            Isometry3::from_parts(Translation3::new(0.0, 0.0, 0.8), UnitQuaternion::from_euler_angles(0.3, 0.2, 0.1));
        let solid = Solid::new(&model, &pose);
        let centre = pose * model.bounding_sphere().0;
        assert!(solid.hides(&(centre * 1.2)));
        assert!(!solid.hides(&(centre * 0.8)));
        assert!(!solid.hides(&(centre + Vector3::new(0.2, 0.0, 0.0))));
        let (mut facing, mut hidden_far) = (0, 0);
        for (k, l) in model.lines.iter().enumerate() {
            let mid = pose * nalgebra::center(&l.a, &l.b);
            if model.faces_camera(k, &pose) {
                facing += 1;
                assert!(!solid.hides(&mid), "camera-facing edge {k} hidden by its own block");
            } else {
                hidden_far += usize::from(solid.hides(&mid));
            }
        }
        assert!(facing >= 5 && hidden_far >= 1, "{facing} edges face the camera, {hidden_far} far ones are hidden");
    }

    /// A block may hide one straight behind it, not one beside it, nor one in front of it.
    #[test]
    fn a_solid_may_hide_only_what_lies_behind_it_in_view() {
        let model = crate::matcher::fixtures::model("block");
        let at = |x: f64, z: f64| Solid::new(&model, &Isometry3::translation(x, 0.0, z));
        let (front, behind, beside) = (at(0.0, 0.7), at(0.0, 0.9), at(0.3, 0.9));
        assert!(front.may_hide(&behind));
        assert!(!front.may_hide(&beside));
        assert!(!at(0.0, 1.2).may_hide(&front));
    }
}
