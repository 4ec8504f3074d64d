//! Occlusion in the image check: where a solid already located in front (or the model's own
//! bulk) hides part of a candidate's wireframe, that part can show no edgels, and counting it
//! as unseen rejects objects that are partly hidden. Solids are the models' triangles at their
//! located poses; a wireframe sample is hidden when the line of sight to it crosses one of them
//! well in front of it.

use super::model::MatcherModel;
use nalgebra::{Isometry3, Point3, Vector3};

/// A model's surface at a pose, in the `cam` frame, with a sphere holding it.
pub struct Solid {
    facets: Vec<Facet>,
    centre: Point3<f64>,
    radius: f64,
}

/// A triangle turned towards the camera at the origin, held as the camera sees it: a line of
/// sight along `d` crosses it where `d` lies inside the three planes through the eye and its
/// edges. Tested this way a sample costs three dot products a triangle, where the general ray
/// test (`mesh::trimesh::ray_triangle`) spends two cross products and two divisions: the polish
/// tests every sample of every pass against the solids, and that was a third of its time.
struct Facet {
    /// `b x c`, `c x a`, `a x b` for corners `a, b, c`: `d` dotted with each is the weight of
    /// the opposite corner in the crossing point, up to a common factor.
    edges: [Vector3<f64>; 3],
    /// `a . (b x c)`, negative for a triangle turned towards the eye; the crossing lies at
    /// `triple / (sum of the weights)` along `d`.
    triple: f64,
    /// The box round the corners' images on the plane z = 1 (`x / z`, `y / z`), a little
    /// widened: a line of sight that crosses the triangle meets that plane inside it.
    lo: [f64; 2],
    hi: [f64; 2],
}

impl Facet {
    fn new([a, b, c]: &[Point3<f64>; 3]) -> Facet {
        let (a, b, c) = (a.coords, b.coords, c.coords);
        let edges = [b.cross(&c), c.cross(&a), a.cross(&b)];
        // Corners behind the eye have no image: the box is then the whole plane.
        let images = [a, b, c].map(|x| (x.z > 0.0).then(|| [x.x / x.z, x.y / x.z]));
        let (mut lo, mut hi) = ([f64::NEG_INFINITY; 2], [f64::INFINITY; 2]);
        if let [Some(p), Some(q), Some(r)] = images {
            for k in 0..2 {
                lo[k] = p[k].min(q[k]).min(r[k]) - BOX_MARGIN;
                hi[k] = p[k].max(q[k]).max(r[k]) + BOX_MARGIN;
            }
        }
        Facet { triple: a.dot(&edges[0]), edges, lo, hi }
    }

    /// Whether the image `at` (on the plane z = 1) of a line of sight lies in the box round
    /// the triangle's image: if not, the line of sight passes it by.
    fn boxes(&self, at: &[f64; 2]) -> bool {
        (0..2).all(|k| self.lo[k] <= at[k] && at[k] <= self.hi[k])
    }

    /// Where the line of sight along `d` crosses the triangle, as a multiple of `d`; `None`
    /// if it passes by.
    fn crossing(&self, d: &Vector3<f64>) -> Option<f64> {
        let w = self.edges.map(|e| e.dot(d));
        // Turned towards the eye, the triangle is crossed where all weights share the
        // triple's (negative) sign.
        let sum = w[0] + w[1] + w[2];
        (w.iter().all(|&x| x <= 0.0) && sum < 0.0).then(|| self.triple / sum)
    }
}

/// How much the box round a facet's image is widened (on the plane z = 1), so that rounding
/// never leaves out a line of sight the exact test would find crossing it.
const BOX_MARGIN: f64 = 1e-9;

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
            facets: model
                .triangles
                .iter()
                .map(|t| t.map(|p| pose * p))
                .filter(facing)
                .map(|t| Facet::new(&t))
                .collect(),
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

    /// How far along the line of sight `d` (from the camera at the origin) it first enters the
    /// solid, as a multiple of `d`: with `d.z` = 1, the depth where it does. `None` if it passes by.
    pub fn entry(&self, d: &Vector3<f64>) -> Option<f64> {
        let per_z = 1.0 / d.z;
        let at = [d.x * per_z, d.y * per_z];
        self.facets
            .iter()
            .filter(|f| d.z <= 0.0 || f.boxes(&at))
            .filter_map(|f| f.crossing(d))
            .filter(|t| *t > 0.0)
            .min_by(|a, b| a.total_cmp(b))
    }

    /// Whether the solid hides point `x` (`cam` frame) from a camera at the origin.
    pub fn hides(&self, x: &Point3<f64>) -> bool {
        let (d, dist) = (x.coords, x.coords.norm());
        // The line of sight must pass through the sphere, in front of the point. (Divisions
        // are dear, and a sample takes several: each divisor's inverse is taken once.)
        let per_dist = 1.0 / dist;
        let along = self.centre.coords.dot(&d) * per_dist;
        if along - self.radius > dist - IN_FRONT_M
            || (d * (along * per_dist) - self.centre.coords).norm_squared() > self.radius * self.radius
        {
            return false;
        }
        let limit = 1.0 - IN_FRONT_M * per_dist;
        let per_z = 1.0 / d.z;
        let at = [d.x * per_z, d.y * per_z];
        let in_front = d.z > 0.0;
        self.facets
            .iter()
            .filter(|f| !in_front || f.boxes(&at))
            .filter_map(|f| f.crossing(&d))
            .any(|t| t > 0.0 && t < limit)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::matcher::fixtures::{Lcg, model};
    use crate::matcher::model::eye_of;
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

    /// The facets' crossing test agrees with the general ray test on random triangles turned
    /// towards the eye and random lines of sight through and past them; the box round a
    /// facet's image holds every line of sight that crosses it, and rules out most of the
    /// others.
    #[test]
    fn a_facet_is_crossed_where_the_general_ray_test_says() {
        let mut rng = crate::matcher::fixtures::Lcg(7);
        let mut point = |z: f64| {
            let [x, y, dz] = [0.2, 0.2, 0.1].map(|w| (rng.next() - 0.5) * w);
            Point3::new(x, y, z + dz)
        };
        let (mut crossed, mut missed, mut boxed_out) = (0, 0, 0);
        for _ in 0..2000 {
            let mut t = [point(0.8), point(0.8), point(0.8)];
            if (t[1] - t[0]).cross(&(t[2] - t[0])).dot(&t[0].coords) > 0.0 {
                t.swap(1, 2);
            }
            let d = point(1.0).coords;
            let general = mesh::trimesh::ray_triangle(&Point3::origin(), &d, &t).filter(|&s| s > 0.0);
            let facet = Facet::new(&t);
            let in_box = facet.boxes(&[d.x / d.z, d.y / d.z]);
            match (facet.crossing(&d), general) {
                (Some(a), Some(b)) => {
                    assert!((a - b).abs() < 1e-9 * b.abs().max(1.0), "crossing at {a} against {b}");
                    assert!(in_box, "a line of sight crossing the facet lies outside its box");
                    crossed += 1;
                }
                (None, None) => {
                    missed += 1;
                    boxed_out += usize::from(!in_box);
                }
                (a, b) => panic!("facet says {a:?}, the ray test {b:?}"),
            }
        }
        assert!(crossed > 200 && missed > 200, "{crossed} crossed, {missed} missed");
        assert!(boxed_out * 2 > missed, "the box rules out only {boxed_out} of the {missed} missed");
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

    /// Over random poses of convex parts before a camera at the origin, a line whose midpoint
    /// the part's own solid leaves in view (a ray test against its triangles) may be seen, and
    /// one that may not be seen is hidden; both kinds occur.
    #[test]
    fn a_line_on_the_far_side_may_not_be_seen_and_is_hidden() {
        let mut rng = Lcg(3);
        let (mut seen, mut unseen) = (0, 0);
        for name in ["block", "wedge", "hex_prism"] {
            let m = model(name);
            for _ in 0..200 {
                let turn = rng.noise(std::f64::consts::PI);
                let pose = Isometry3::from_parts(
                    Translation3::from(Vector3::new(0.0, 0.0, 0.8) + rng.noise(0.1)),
                    UnitQuaternion::from_scaled_axis(turn),
                );
                let (solid, eye) = (Solid::new(&m, &pose), eye_of(&pose));
                for k in 0..m.lines.len() {
                    let mid = pose * nalgebra::center(&m.lines[k].a, &m.lines[k].b);
                    let hidden = solid.hides(&mid);
                    if !hidden {
                        assert!(m.may_be_seen(k, &eye), "{name}: line {k} in view but ruled out at {pose:?}");
                        seen += 1;
                    }
                    if !m.may_be_seen(k, &eye) {
                        assert!(hidden, "{name}: line {k} ruled out but in view at {pose:?}");
                        unseen += 1;
                    }
                }
            }
        }
        assert!(seen > 1000 && unseen > 1000, "{seen} lines in view, {unseen} ruled out");
    }
}
