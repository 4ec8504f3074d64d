//! The strict judge of a pick, from the physics alone: whether a part counts as placed in a bin,
//! and which part a pick request aimed at.
//!
//! A part is placed only when all of these hold:
//! - it is at rest;
//! - the box around it (world axes, its colliders as they stand) lies inside the bin's inner
//!   walls, give or take the contacts' slack: a part balanced on a wall or hanging over the rim
//!   is not in the bin;
//! - its top is no higher than the rim plus the part's own largest dimension: a part lying on
//!   the pile in the bin counts, one stood on end on top of it does not;
//! - it touches neither finger: a part left leaning on the jaws has not been let go.
//!
//! A pick is at the part whose pose the request carried: the body nearest that pose when the
//! jaws close. If another body is lifted, the pick is a `wrong_part`, wherever it lands.

use nalgebra::Isometry3;
use rapier3d::prelude::RigidBodyHandle;
use sim::physics::Cell;
use sim::world::BinSpec;

/// How far a part's box may reach past the bin's inner walls and still be inside them, metres:
/// the contacts' interpenetration and the walls' contact skin (rapier rests bodies within about
/// a millimetre of each other).
pub const WALL_SLACK_M: f64 = 0.002;
/// A part this near a finger is touching it, metres.
pub const FINGER_GAP_M: f64 = 0.001;
/// A part slower than this is at rest, m/s.
pub const AT_REST_M_S: f64 = 0.01;

/// The geometry of a part and what it must not touch, as the judge needs them.
pub struct Part<'a> {
    pub body: RigidBodyHandle,
    /// Its model (the body's frame is the model's).
    pub model: &'a mesh::Model,
    /// The gripper's finger bodies.
    pub fingers: &'a [RigidBodyHandle],
}

impl Part<'_> {
    /// The world-axis box around the part's model where the body stands: (mins, maxs).
    fn world_box(&self, cell: &Cell) -> ([f64; 3], [f64; 3]) {
        let world_from_model = cell.pose(self.body);
        let (mut lo, mut hi) = ([f64::MAX; 3], [f64::MIN; 3]);
        for v in &self.model.mesh.vertices {
            let p = world_from_model * v;
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        (lo, hi)
    }
}

/// Why the part does not count as placed in `bin`, or `None` when it does.
pub fn why_not_placed(cell: &Cell, part: &Part, bin: &BinSpec) -> Option<String> {
    let b = &cell.world.bodies[part.body];
    let speed = b.linvel().length() as f64;
    if speed >= AT_REST_M_S {
        return Some(format!("it was still moving ({:.0} mm/s)", speed * 1e3));
    }
    let (lo, hi) = part.world_box(cell);
    let [ix, iy, wall_h] = bin.size_m;
    let inner = [(bin.centre_m[0], ix / 2.0), (bin.centre_m[1], iy / 2.0)];
    for (k, (centre, half)) in inner.into_iter().enumerate() {
        let (from, to) = (centre - half - WALL_SLACK_M, centre + half + WALL_SLACK_M);
        if lo[k] < from || hi[k] > to {
            let axis = ["x", "y"][k];
            return Some(format!(
                "it reaches from {:.3} to {:.3} m in {axis}, outside the bin's inner walls ({:.3} to {:.3})",
                lo[k],
                hi[k],
                centre - half,
                centre + half
            ));
        }
    }
    let ceiling = bin.wall_m + wall_h + part.model.extent().max();
    if hi[2] > ceiling {
        return Some(format!(
            "its top is at {:.3} m, over the rim plus its own largest dimension ({ceiling:.3} m)",
            hi[2]
        ));
    }
    if part.fingers.iter().any(|&f| cell.touching(part.body, f, FINGER_GAP_M)) {
        return Some("it rests against a finger".into());
    }
    None
}

/// The body (of `bodies`) nearest the pose a request carried, by the distance between their
/// model frames' origins.
pub fn aimed_at(
    cell: &Cell,
    bodies: impl IntoIterator<Item = RigidBodyHandle>,
    world_from_model: &Isometry3<f64>,
) -> Option<RigidBodyHandle> {
    let distance =
        |b: &RigidBodyHandle| (cell.pose(*b).translation.vector - world_from_model.translation.vector).norm();
    bodies.into_iter().min_by(|a, b| distance(a).total_cmp(&distance(b)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::server::pick::{PickCell, load};
    use nalgebra::{Isometry3, Vector3};

    /// A settled ideal clutter scene with the arm at home, its first bin, and a block of it
    /// (its body and model).
    fn with_a_block(test: impl FnOnce(&mut PickCell, &BinSpec, RigidBodyHandle, &mesh::Model)) {
        let world = concat!(env!("CARGO_MANIFEST_DIR"), "/worlds/ideal/widgets.toml");
        let (scn, work) = load(world.as_ref()).unwrap();
        let scene = sim::scene::Scene::settle(&scn, 3);
        let mut cell = PickCell::new(&scn, &work, &scene).unwrap();
        let &(_, ref model, body) = cell.objects.iter().find(|(_, m, _)| m == "block").expect("a block in seed 3");
        let model = scn.library.models[model].clone();
        let bin = scn.world.bins[0].clone();
        test(&mut cell, &bin, body, &model);
    }

    /// Puts a body at `world_from_model`, at rest (no step taken: the rule is judged on the pose).
    fn put(cell: &mut PickCell, body: RigidBodyHandle, world_from_model: &Isometry3<f64>) {
        let b = &mut cell.cell.world.bodies[body];
        b.set_position(sim::convert::pose(world_from_model), true);
        b.set_linvel(Default::default(), true);
        b.set_angvel(Default::default(), true);
    }

    /// Where the block's centre of mass lands for a model frame at `(x, y, z)`, unrotated.
    fn at(cell: &PickCell, body: RigidBodyHandle, x: f64, y: f64, z: f64) -> Isometry3<f64> {
        let com = cell.cell.world.bodies[body].center_of_mass();
        let local = cell.cell.pose(body).inverse() * nalgebra::Point3::new(com.x as f64, com.y as f64, com.z as f64);
        Isometry3::translation(x, y, z) * Isometry3::translation(-local.x, -local.y, -local.z)
    }

    #[test]
    fn a_block_on_the_bins_floor_is_placed() {
        with_a_block(|cell, bin, body, model| {
            let (lo, hi) = cell.cell.world_aabb(body);
            let half_h = (hi[2] - lo[2]) / 2.0;
            let p = at(cell, body, bin.centre_m[0], bin.centre_m[1], bin.wall_m + half_h + 1e-4);
            put(cell, body, &p);
            let part = Part { body, model, fingers: &cell.arm.finger_bodies };
            assert_eq!(why_not_placed(&cell.cell, &part, bin), None);
        });
    }

    /// Its centre over the floor (which the old rule asked), its box over the wall: not in.
    #[test]
    fn a_block_across_a_wall_is_not_placed() {
        with_a_block(|cell, bin, body, model| {
            let x = bin.centre_m[0] + bin.size_m[0] / 2.0 - 0.01;
            let p = at(cell, body, x, bin.centre_m[1], bin.wall_m + bin.size_m[2] + 0.02);
            put(cell, body, &p);
            let part = Part { body, model, fingers: &cell.arm.finger_bodies };
            let why = why_not_placed(&cell.cell, &part, bin).expect("over the wall");
            assert!(why.contains("inner walls"), "{why}");
        });
    }

    /// Over the floor and inside the walls' line, but higher than the rim plus the block's own
    /// largest dimension (and lower than the old three bin depths): not in.
    #[test]
    fn a_block_high_over_the_rim_is_not_placed() {
        with_a_block(|cell, bin, body, model| {
            let z = bin.wall_m + bin.size_m[2] + model.extent().max() + 0.01;
            assert!(z < bin.wall_m + 3.0 * bin.size_m[2], "the old rule would have let it pass");
            let p = at(cell, body, bin.centre_m[0], bin.centre_m[1], z);
            put(cell, body, &p);
            let part = Part { body, model, fingers: &cell.arm.finger_bodies };
            let why = why_not_placed(&cell.cell, &part, bin).expect("too high");
            assert!(why.contains("rim"), "{why}");
        });
    }

    #[test]
    fn a_moving_block_is_not_placed() {
        with_a_block(|cell, bin, body, model| {
            let (lo, hi) = cell.cell.world_aabb(body);
            let p = at(cell, body, bin.centre_m[0], bin.centre_m[1], bin.wall_m + (hi[2] - lo[2]) / 2.0 + 1e-4);
            put(cell, body, &p);
            cell.cell.world.bodies[body].set_linvel(rapier3d::prelude::Vector::new(0.0, 0.0, -0.5), true);
            let part = Part { body, model, fingers: &cell.arm.finger_bodies };
            assert!(why_not_placed(&cell.cell, &part, bin).is_some_and(|w| w.contains("moving")));
        });
    }

    /// A block lying in the bin against a finger has not been let go. The finger here is the
    /// body the judge is told is one: another part of the scene put against the block.
    #[test]
    fn a_block_touching_a_finger_is_not_placed() {
        with_a_block(|cell, bin, body, model| {
            let other = cell.objects.iter().map(|o| o.2).find(|b| *b != body).unwrap();
            let (lo, hi) = cell.cell.world_aabb(body);
            let half_h = (hi[2] - lo[2]) / 2.0;
            let p = at(cell, body, bin.centre_m[0], bin.centre_m[1], bin.wall_m + half_h + 1e-4);
            put(cell, body, &p);
            let fingers = [other];
            let part = Part { body, model, fingers: &fingers };
            assert_eq!(why_not_placed(&cell.cell, &part, bin), None, "the other part is elsewhere");
            // The other part stood right on top of the block.
            let (olo, ohi) = cell.cell.world_aabb(other);
            let shift = Vector3::new(
                bin.centre_m[0] - (olo[0] + ohi[0]) / 2.0,
                bin.centre_m[1] - (olo[1] + ohi[1]) / 2.0,
                hi[2] - olo[2] + 2e-4,
            );
            put(cell, other, &(Isometry3::from_parts(shift.into(), Default::default()) * cell.cell.pose(other)));
            let why = why_not_placed(&cell.cell, &part, bin).expect("against a finger");
            assert!(why.contains("finger"), "{why}");
        });
    }

    #[test]
    fn the_body_aimed_at_is_the_one_nearest_the_pose_the_request_carried() {
        with_a_block(|cell, _, body, _| {
            let pose = cell.cell.pose(body) * Isometry3::translation(0.004, -0.003, 0.002);
            let bodies = cell.objects.iter().map(|o| o.2);
            assert_eq!(aimed_at(&cell.cell, bodies, &pose), Some(body));
        });
    }
}
