//! The strict judge's rules (`src/server/judge.rs`), each on a part put where the rule decides,
//! in a settled ideal scene with the arm at home: what a part must be to count as placed, and
//! which part a request aimed at. Each rule's test fails without the rule.

use marvin::server::judge::{Part, aimed_at, why_not_placed};
use marvin::server::pick::{PickCell, load};
use nalgebra::{Isometry3, Vector3};
use rapier3d::prelude::RigidBodyHandle;
use sim::world::BinSpec;

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
