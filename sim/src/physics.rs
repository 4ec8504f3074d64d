//! The rapier world of the cell: fixed boxes, dynamic objects with the mass properties their
//! models give, and settling until everything is at rest.

use crate::convert;
use crate::world::PhysicsSpec;
use mesh::Model;
use mesh::TriMesh;
use mesh::model::Collision;
use nalgebra::{Isometry3, Vector3};
use rapier3d::prelude::*;

/// A fixed box of the cell: floor, table top, bin walls.
#[derive(Debug, Clone, PartialEq)]
pub struct StaticBox {
    pub name: String,
    pub world_from_box: Isometry3<f64>,
    pub half_extents: Vector3<f64>,
    pub albedo: f64,
}

impl StaticBox {
    pub(crate) fn at(name: String, centre: [f64; 3], half: [f64; 3], albedo: f64) -> Self {
        StaticBox {
            name,
            world_from_box: Isometry3::translation(centre[0], centre[1], centre[2]),
            half_extents: Vector3::from(half),
            albedo,
        }
    }

    pub fn mesh(&self) -> TriMesh {
        TriMesh::cuboid(self.half_extents, self.albedo as f32).transformed(&self.world_from_box)
    }
}

/// Speeds under which a body counts as at rest (m/s and rad/s).
const REST_LINEAR: f32 = 2e-3;
const REST_ANGULAR: f32 = 2e-2;
/// How long every body must stay under those speeds.
const REST_HOLD_S: f64 = 0.25;

/// The rapier side of the cell.
pub struct Cell {
    pub world: PhysicsWorld,
    pub objects: Vec<RigidBodyHandle>,
    friction: f32,
}

/// How settling went.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SettleReport {
    pub simulated_s: f64,
    pub steps: u32,
    /// True when every object stayed at rest for a while before the time limit.
    pub at_rest: bool,
    pub max_linear_speed: f64,
    pub max_angular_speed: f64,
    /// Deepest interpenetration of any two colliders at the end, metres.
    pub max_contact_depth: f64,
    /// How many drops it took (a drop that ends interpenetrating is redone, see `Scene::settle`).
    pub drops: u32,
}

/// The natural frequency of contacts between moving bodies (Hz; rapier's default is 30).
pub const CONTACT_FREQUENCY_HZ: f32 = 200.0;

impl Cell {
    pub fn new(spec: &PhysicsSpec, statics: &[StaticBox]) -> Cell {
        let mut world = PhysicsWorld::new();
        world.gravity = Vector::new(0.0, 0.0, -9.81);
        world.integration_parameters.dt = spec.timestep_s as f32;
        // Rapier's defaults (soft 30 Hz contacts, clustered manifolds, simplified friction) let
        // compound objects walk and sink by millimetres; these settings, measured over 150 clutter
        // seeds, bring every scene to rest with sub-millimetre contact depths.
        let ip = &mut world.integration_parameters;
        ip.normalized_allowed_linear_error = 2e-4;
        ip.num_solver_iterations = 8;
        ip.num_internal_stabilization_iterations = 4;
        ip.contact_softness.natural_frequency = CONTACT_FREQUENCY_HZ;
        ip.static_contact_softness.natural_frequency = 400.0;
        ip.friction_model = FrictionModel::Coulomb;
        ip.contact_clustering = false;
        let friction = spec.friction as f32;
        for b in statics {
            let h = convert::vector(&b.half_extents);
            world.insert(
                RigidBodyBuilder::fixed().pose(convert::pose(&b.world_from_box)),
                ColliderBuilder::cuboid(h.x, h.y, h.z).friction(friction),
            );
        }
        Cell { world, objects: Vec::new(), friction }
    }

    /// Adds a dynamic body for `model` at `world_from_model`; the body frame is the model frame.
    pub fn add_object(&mut self, model: &Model, world_from_model: &Isometry3<f64>) -> RigidBodyHandle {
        let handle = self.add_body(model, world_from_model);
        self.objects.push(handle);
        handle
    }

    /// A body of `model` that is not one of the scene's objects (settling ignores it): a tool
    /// handed into the gripper.
    pub fn add_tool(&mut self, model: &Model, world_from_model: &Isometry3<f64>) -> RigidBodyHandle {
        self.add_body(model, world_from_model)
    }

    fn add_body(&mut self, model: &Model, world_from_model: &Isometry3<f64>) -> RigidBodyHandle {
        let mp = &model.mass;
        let mass = MassProperties::with_inertia_matrix(
            convert::point(&mp.centre_of_mass),
            mp.mass as f32,
            convert::matrix(&mp.inertia),
        );
        let body = RigidBodyBuilder::dynamic()
            .pose(convert::pose(world_from_model))
            .additional_mass_properties(mass)
            .ccd_enabled(true);
        let collider =
            ColliderBuilder::new(collision_shape(model)).density(0.0).friction(self.friction).restitution(0.05);
        let (handle, _) = self.world.insert(body, collider);
        handle
    }

    /// Fixes boxes to a body, each `(world_from_box, half_extents)` in metres, where they are now:
    /// a tool's locating features, which its model's shape does not have, or its jaw inserts on
    /// a finger. Returns their colliders.
    pub fn attach_boxes(
        &mut self,
        body: RigidBodyHandle,
        boxes: &[(Isometry3<f64>, Vector3<f64>)],
    ) -> Vec<ColliderHandle> {
        let world_from_body = convert::iso(self.world.bodies[body].position());
        boxes
            .iter()
            .map(|(world_from_box, h)| {
                let h = convert::vector(h);
                let collider = ColliderBuilder::cuboid(h.x, h.y, h.z)
                    .position(convert::pose(&(world_from_body.inverse() * world_from_box)))
                    .density(0.0)
                    .friction(self.friction);
                let w = &mut self.world;
                w.colliders.insert_with_parent(collider, body, &mut w.bodies)
            })
            .collect()
    }

    /// Takes colliders out of the world (their body stays).
    pub fn detach(&mut self, colliders: &[ColliderHandle]) {
        for &c in colliders {
            self.world.remove_collider(c);
        }
    }

    /// Holds a body where it is (the operator's hand) or lets it go.
    pub fn hold_in_place(&mut self, body: RigidBodyHandle, held: bool) {
        let kind = if held { RigidBodyType::KinematicPositionBased } else { RigidBodyType::Dynamic };
        self.world.bodies[body].set_body_type(kind, true);
    }

    /// Takes a body (and its collider) out of the world.
    pub fn remove(&mut self, body: RigidBodyHandle) {
        self.world.remove_body(body);
        self.objects.retain(|&b| b != body);
    }

    pub fn pose(&self, body: RigidBodyHandle) -> Isometry3<f64> {
        convert::iso(self.world.bodies[body].position())
    }

    /// The world-axis box around a body's colliders as they stand now: (mins, maxs), metres.
    pub fn world_aabb(&self, body: RigidBodyHandle) -> ([f64; 3], [f64; 3]) {
        let (mut lo, mut hi) = ([f64::MAX; 3], [f64::MIN; 3]);
        for (pose, shape) in self.collider_poses(body) {
            let aabb = shape.compute_aabb(&pose);
            for k in 0..3 {
                lo[k] = lo[k].min(aabb.mins[k] as f64);
                hi[k] = hi[k].max(aabb.maxs[k] as f64);
            }
        }
        (lo, hi)
    }

    /// Whether two bodies' colliders are within `gap_m` of each other (touching, give or take
    /// the contacts' own slack): parry's exact distance on the simulated shapes.
    pub fn touching(&self, a: RigidBodyHandle, b: RigidBodyHandle, gap_m: f64) -> bool {
        let (xs, ys) = (self.collider_poses(a), self.collider_poses(b));
        xs.iter().any(|(px, x)| {
            ys.iter()
                .any(|(py, y)| matches!(rapier3d::parry::query::contact(px, *x, py, *y, gap_m as f32), Ok(Some(_))))
        })
    }

    /// A body's colliders where the body stands now (also before a step has moved the
    /// colliders after the body was put somewhere).
    fn collider_poses(&self, body: RigidBodyHandle) -> Vec<(Pose, &dyn Shape)> {
        let b = &self.world.bodies[body];
        b.colliders()
            .iter()
            .map(|&c| {
                let collider = &self.world.colliders[c];
                let pose = match collider.position_wrt_parent() {
                    Some(rel) => *b.position() * *rel,
                    None => *collider.position(),
                };
                (pose, collider.shape())
            })
            .collect()
    }

    /// Steps until every object has been at rest for a while, or `limit_s` of simulated time.
    pub fn settle(&mut self, limit_s: f64) -> SettleReport {
        let dt = self.world.integration_parameters.dt as f64;
        let (mut steps, mut calm_s) = (0u32, 0.0);
        loop {
            self.world.step();
            steps += 1;
            let (lin, ang) = self.max_speeds();
            calm_s = if lin < REST_LINEAR && ang < REST_ANGULAR { calm_s + dt } else { 0.0 };
            let simulated_s = steps as f64 * dt;
            if calm_s >= REST_HOLD_S || simulated_s >= limit_s {
                return SettleReport {
                    simulated_s,
                    steps,
                    at_rest: calm_s >= REST_HOLD_S,
                    max_linear_speed: lin as f64,
                    max_angular_speed: ang as f64,
                    max_contact_depth: self.max_contact_depth(),
                    drops: 1,
                };
            }
        }
    }

    /// The deepest interpenetration between an object and anything else, metres (parry's exact
    /// contact query on the simulated shapes).
    pub fn max_contact_depth(&self) -> f64 {
        let colliders: Vec<&Collider> = self.world.colliders.iter().map(|(_, c)| c).collect();
        let mut deepest = 0.0f32;
        for (i, a) in colliders.iter().enumerate() {
            for b in &colliders[i + 1..] {
                if !(self.is_object(a) || self.is_object(b)) {
                    continue;
                }
                let contact = rapier3d::parry::query::contact(a.position(), a.shape(), b.position(), b.shape(), 0.0);
                if let Ok(Some(c)) = contact {
                    deepest = deepest.max(-c.dist);
                }
            }
        }
        deepest as f64
    }

    fn is_object(&self, c: &Collider) -> bool {
        c.parent().is_some_and(|p| self.objects.contains(&p))
    }

    fn max_speeds(&self) -> (f32, f32) {
        self.objects.iter().fold((0.0f32, 0.0f32), |(l, a), &h| {
            let b = &self.world.bodies[h];
            (l.max(b.linvel().length()), a.max(b.angvel().length()))
        })
    }
}

/// The shape rapier simulates for a model: its exact convex pieces, or an approximate
/// decomposition of a non-convex mesh.
pub fn collision_shape(model: &Model) -> SharedShape {
    match &model.collision {
        Collision::ConvexPieces(pieces) => {
            let mut hulls: Vec<(Pose, SharedShape)> = pieces
                .iter()
                .map(|pts| {
                    let pts: Vec<Vector> = pts.iter().map(convert::point).collect();
                    let hull = SharedShape::convex_hull(&pts).expect("model pieces are solid");
                    (Pose::IDENTITY, hull)
                })
                .collect();
            if hulls.len() == 1 { hulls.remove(0).1 } else { SharedShape::compound(hulls) }
        }
        Collision::Decompose => {
            let pts: Vec<Vector> = model.mesh.vertices.iter().map(convert::point).collect();
            SharedShape::convex_decomposition(&pts, &model.mesh.triangles)
        }
    }
}
