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
//!
//! Each rule's test is in `tests/judge.rs` (it builds a cell with [`super::pick`], which uses
//! this file).

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
