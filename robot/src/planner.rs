//! Collision-aware joint-space paths: the arm's link shapes against the scene's obstacles as parry
//! shapes, RRT-Connect between two configurations, then shortcutting.
//!
//! Hand-written rather than the `rrt` crate: that crate shortcuts with an unseeded thread RNG
//! (runs would not be repeatable from the seed) and checks only sampled points, not the
//! segments between them. Here every segment is checked densely ([`RESOLUTION`]) and every
//! random choice comes from the caller's seed.

use crate::arm::{Arm, Joints, Primitive};
use crate::ik::distance;
use nalgebra::{Isometry3, Vector3};
use parry3d::math::{Pose, Rotation, Vector};
use parry3d::shape::SharedShape;
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

/// Largest joint step between collision checks along a segment: about 4 mm of motion at the
/// fingertips for each joint (zed in metres, the rest in radians).
pub const RESOLUTION: Joints = [0.004, 0.0067, 0.011, 0.027, 0.027, 0.027];

/// Something the arm must not touch, in the base frame.
#[derive(Clone)]
pub struct Obstacle {
    pub name: String,
    pub shape: SharedShape,
    pub base_from_shape: Isometry3<f64>,
}

/// A shape carried in the gripper (a grasped object), which must not touch obstacles either.
#[derive(Clone)]
pub struct Attached {
    pub shape: SharedShape,
    pub gripper_from_shape: Isometry3<f64>,
}

/// A detected collision: which arm part touches which obstacle.
#[derive(Debug, Clone, PartialEq)]
pub struct Collision {
    pub part: String,
    pub obstacle: String,
}

struct Part {
    link: usize,
    link_from_shape: Isometry3<f64>,
    shape: SharedShape,
    radius: f64,
}

/// The arm's moving link shapes and the obstacles around it.
pub struct CollisionWorld {
    parts: Vec<Part>,
    obstacles: Vec<(Obstacle, f64, Vector3<f64>)>,
    tcp_link: usize,
    /// Parts must stay at least this far from obstacles, metres.
    pub clearance: f64,
}

impl CollisionWorld {
    /// The arm's shapes (all but the root link's, which stands on the table by design) against
    /// `obstacles`.
    pub fn new(arm: &Arm, obstacles: Vec<Obstacle>, clearance: f64) -> CollisionWorld {
        let root = arm.joints[arm.arm_joints[0]].parent;
        let parts = arm
            .links
            .iter()
            .enumerate()
            .filter(|(i, _)| *i != root)
            .flat_map(|(link, spec)| {
                spec.shapes.iter().map(move |s| {
                    let (shape, shape_from_parry) = parry_shape(&s.primitive);
                    let link_from_shape = s.link_from_shape * shape_from_parry;
                    let radius = bounding_radius(&shape);
                    Part { link, link_from_shape, shape, radius }
                })
            })
            .collect();
        let obstacles = obstacles
            .into_iter()
            .map(|o| {
                let (r, c) = bounding_sphere(&o.shape);
                let centre = o.base_from_shape * nalgebra::Point3::from(c);
                (o, r, centre.coords)
            })
            .collect();
        CollisionWorld { parts, obstacles, tcp_link: arm.tcp_link, clearance }
    }

    pub fn obstacle_names(&self) -> impl Iterator<Item = &str> {
        self.obstacles.iter().map(|(o, _, _)| o.name.as_str())
    }

    /// The first contact of the arm (and what it carries) with an obstacle at `q`, if any.
    pub fn collision(&self, arm: &Arm, q: &Joints, opening: f64, attached: Option<&Attached>) -> Option<Collision> {
        let poses = arm.link_poses(q, opening);
        for part in &self.parts {
            let pose = poses[part.link] * part.link_from_shape;
            if let Some(name) = self.touching(&pose, &part.shape, part.radius) {
                return Some(Collision { part: arm.links[part.link].name.clone(), obstacle: name.to_string() });
            }
        }
        if let Some(att) = attached {
            let pose = poses[self.tcp_link] * att.gripper_from_shape;
            let (r, c) = bounding_sphere(&att.shape);
            if let Some(name) = self.touching_offset(&pose, &att.shape, r, c) {
                return Some(Collision { part: "held object".into(), obstacle: name.to_string() });
            }
        }
        None
    }

    fn touching(&self, pose: &Isometry3<f64>, shape: &SharedShape, radius: f64) -> Option<&str> {
        self.touching_offset(pose, shape, radius, Vector3::zeros())
    }

    /// The first obstacle within the clearance of `shape` at `pose`, whose bounding sphere has
    /// `radius` about the shape-frame point `centre`.
    fn touching_offset(
        &self,
        pose: &Isometry3<f64>,
        shape: &SharedShape,
        radius: f64,
        centre: Vector3<f64>,
    ) -> Option<&str> {
        let world_centre = pose * nalgebra::Point3::from(centre);
        let parry_pose = to_parry(pose);
        for (o, r, c) in &self.obstacles {
            if (world_centre.coords - c).norm() > radius + r + self.clearance {
                continue;
            }
            let d =
                parry3d::query::distance(&parry_pose, shape.as_ref(), &to_parry(&o.base_from_shape), o.shape.as_ref())
                    .map(|d| d.distance as f64)
                    .unwrap_or(0.0);
            if d <= self.clearance {
                return Some(&o.name);
            }
        }
        None
    }

    /// Whether the straight joint-space segment `a`-`b` is free, checked every [`RESOLUTION`].
    pub fn segment_collision(
        &self,
        arm: &Arm,
        a: &Joints,
        b: &Joints,
        opening: f64,
        attached: Option<&Attached>,
    ) -> Option<Collision> {
        let steps = (0..6).map(|k| ((b[k] - a[k]).abs() / RESOLUTION[k]).ceil() as usize).max().unwrap_or(0).max(1);
        (0..=steps).find_map(|i| {
            let u = i as f64 / steps as f64;
            let q = std::array::from_fn(|k| a[k] + u * (b[k] - a[k]));
            self.collision(arm, &q, opening, attached)
        })
    }
}

/// Why no path was found.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlanError {
    #[error("the start configuration collides: {} touches {}", .0.part, .0.obstacle)]
    StartInCollision(Collision),
    #[error("the goal configuration collides: {} touches {}", .0.part, .0.obstacle)]
    GoalInCollision(Collision),
    #[error("no collision-free path after {0} RRT-Connect iterations")]
    NoPath(usize),
}

/// RRT-Connect settings.
#[derive(Debug, Clone, Copy)]
pub struct PlannerParams {
    pub max_iterations: usize,
    /// Tree extension step in the weighted joint metric of [`distance`].
    pub step: f64,
    pub shortcut_rounds: usize,
}

impl Default for PlannerParams {
    fn default() -> Self {
        PlannerParams { max_iterations: 4000, step: 0.25, shortcut_rounds: 80 }
    }
}

/// One planning problem: the arm among obstacles, with the gripper at `opening` and maybe
/// carrying `attached`.
pub struct Problem<'a> {
    pub arm: &'a Arm,
    pub world: &'a CollisionWorld,
    pub opening: f64,
    pub attached: Option<&'a Attached>,
}

impl Problem<'_> {
    fn free(&self, a: &Joints, b: &Joints) -> bool {
        self.world.segment_collision(self.arm, a, b, self.opening, self.attached).is_none()
    }

    /// A collision-free path from `start` to `goal`: the straight segment when it is free,
    /// otherwise RRT-Connect and shortcutting.
    pub fn plan(
        &self,
        start: &Joints,
        goal: &Joints,
        params: &PlannerParams,
        seed: u64,
    ) -> Result<Vec<Joints>, PlanError> {
        if let Some(c) = self.world.collision(self.arm, start, self.opening, self.attached) {
            return Err(PlanError::StartInCollision(c));
        }
        if let Some(c) = self.world.collision(self.arm, goal, self.opening, self.attached) {
            return Err(PlanError::GoalInCollision(c));
        }
        if self.free(start, goal) {
            return Ok(vec![*start, *goal]);
        }
        let mut rng = StdRng::seed_from_u64(seed);
        let mut path = self.rrt_connect(start, goal, params, &mut rng)?;
        self.shortcut(&mut path, params.shortcut_rounds, &mut rng);
        Ok(path)
    }

    fn rrt_connect(
        &self,
        start: &Joints,
        goal: &Joints,
        p: &PlannerParams,
        rng: &mut StdRng,
    ) -> Result<Vec<Joints>, PlanError> {
        let (lo, hi) = (self.arm.lower(), self.arm.upper());
        let mut a = Tree::new(*start);
        let mut b = Tree::new(*goal);
        for _ in 0..p.max_iterations {
            let sample: Joints = std::array::from_fn(|k| rng.random_range(lo[k]..hi[k]));
            if let Some(new) = self.extend(&mut a, &sample, p.step) {
                let target = a.nodes[new].0;
                if let Some(reached) = self.connect(&mut b, &target, p.step) {
                    let (from_a, from_b) = (a.path_to(new), b.path_to(reached));
                    let mut path = from_a;
                    path.extend(from_b.into_iter().rev().skip(1));
                    if path[0] != *start {
                        path.reverse();
                    }
                    return Ok(path);
                }
            }
            std::mem::swap(&mut a, &mut b);
        }
        Err(PlanError::NoPath(p.max_iterations))
    }

    /// Grows `tree` one step from its node nearest `towards`; the new node's index.
    fn extend(&self, tree: &mut Tree, towards: &Joints, step: f64) -> Option<usize> {
        let near = tree.nearest(towards);
        let from = tree.nodes[near].0;
        let d = distance(&from, towards);
        let to =
            if d <= step { *towards } else { std::array::from_fn(|k| from[k] + (towards[k] - from[k]) * step / d) };
        self.free(&from, &to).then(|| tree.add(to, near))
    }

    /// Extends `tree` towards `target` until it gets there (its node index) or is stopped.
    fn connect(&self, tree: &mut Tree, target: &Joints, step: f64) -> Option<usize> {
        loop {
            let new = self.extend(tree, target, step)?;
            if distance(&tree.nodes[new].0, target) < 1e-12 {
                return Some(new);
            }
        }
    }

    /// Replaces stretches of the path by straight segments where those are free.
    fn shortcut(&self, path: &mut Vec<Joints>, rounds: usize, rng: &mut StdRng) {
        for _ in 0..rounds {
            if path.len() < 3 {
                return;
            }
            let i = rng.random_range(0..path.len() - 2);
            let j = rng.random_range(i + 2..path.len());
            if self.free(&path[i], &path[j]) {
                path.drain(i + 1..j);
            }
        }
    }
}

struct Tree {
    nodes: Vec<(Joints, usize)>,
}

impl Tree {
    fn new(root: Joints) -> Tree {
        Tree { nodes: vec![(root, usize::MAX)] }
    }

    fn add(&mut self, q: Joints, parent: usize) -> usize {
        self.nodes.push((q, parent));
        self.nodes.len() - 1
    }

    fn nearest(&self, q: &Joints) -> usize {
        (0..self.nodes.len())
            .min_by(|&a, &b| distance(&self.nodes[a].0, q).total_cmp(&distance(&self.nodes[b].0, q)))
            .unwrap()
    }

    /// Root to `node`.
    fn path_to(&self, mut node: usize) -> Vec<Joints> {
        let mut path = vec![];
        while node != usize::MAX {
            path.push(self.nodes[node].0);
            node = self.nodes[node].1;
        }
        path.reverse();
        path
    }
}

/// A primitive as a parry shape, with the pose of parry's shape frame in the primitive's frame
/// (parry's cylinders stand along y, URDF's along z).
fn parry_shape(p: &Primitive) -> (SharedShape, Isometry3<f64>) {
    let f = |x: f64| x as f32;
    match *p {
        Primitive::Box { half_extents: h } => (SharedShape::cuboid(f(h.x), f(h.y), f(h.z)), Isometry3::identity()),
        Primitive::Cylinder { radius, half_length } => (
            SharedShape::cylinder(f(half_length), f(radius)),
            Isometry3::rotation(Vector3::x() * std::f64::consts::FRAC_PI_2),
        ),
        Primitive::Sphere { radius } => (SharedShape::ball(f(radius)), Isometry3::identity()),
        Primitive::Capsule { radius, half_length } => {
            (SharedShape::capsule_z(f(half_length), f(radius)), Isometry3::identity())
        }
    }
}

fn bounding_sphere(shape: &SharedShape) -> (f64, Vector3<f64>) {
    let aabb = shape.compute_local_aabb();
    let (c, h) = (aabb.center(), aabb.half_extents());
    (h.length() as f64, Vector3::new(c.x as f64, c.y as f64, c.z as f64))
}

fn bounding_radius(shape: &SharedShape) -> f64 {
    let (r, c) = bounding_sphere(shape);
    r + c.norm()
}

/// The planner's one crossing from nalgebra (f64) into parry's glam (f32) types.
pub fn to_parry(iso: &Isometry3<f64>) -> Pose {
    let q = iso.rotation.quaternion();
    let t = iso.translation.vector;
    let rotation = Rotation::from_xyzw(q.i as f32, q.j as f32, q.k as f32, q.w as f32).normalize();
    Pose::from_parts(Vector::new(t.x as f32, t.y as f32, t.z as f32), rotation)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::arm::tests::umi;
    use crate::trajectory::{Limits, Trajectory};

    fn boxed(name: &str, centre: [f64; 3], half: [f32; 3]) -> Obstacle {
        Obstacle {
            name: name.into(),
            shape: SharedShape::cuboid(half[0], half[1], half[2]),
            base_from_shape: Isometry3::translation(centre[0], centre[1], centre[2]),
        }
    }

    /// A table top at z = 0 and a wall standing between the arm's two sides.
    fn scene() -> Vec<Obstacle> {
        vec![boxed("table", [0.3, 0.0, -0.05], [0.6, 0.6, 0.05]), boxed("wall", [0.3, 0.0, 0.15], [0.08, 0.01, 0.15])]
    }

    /// Every link shape against every obstacle by parry's intersection test, independently of
    /// the planner's distance queries.
    fn touches(arm: &Arm, obstacles: &[Obstacle], q: &Joints, opening: f64) -> Option<String> {
        let poses = arm.link_poses(q, opening);
        let root = arm.joints[arm.arm_joints[0]].parent;
        for (i, link) in arm.links.iter().enumerate().filter(|(i, _)| *i != root) {
            for s in &link.shapes {
                let (shape, parry_from) = parry_shape(&s.primitive);
                let pose = to_parry(&(poses[i] * s.link_from_shape * parry_from));
                for o in obstacles {
                    let hit = parry3d::query::intersection_test(
                        &pose,
                        shape.as_ref(),
                        &to_parry(&o.base_from_shape),
                        o.shape.as_ref(),
                    );
                    if hit.is_ok_and(|h| h.intersecting) {
                        return Some(format!("{} hits {}", link.name, o.name));
                    }
                }
            }
        }
        None
    }

    #[test]
    fn paths_around_a_wall_are_collision_free_along_the_whole_trajectory() {
        let arm = umi();
        let world = CollisionWorld::new(&arm, scene(), 0.005);
        let problem = Problem { arm: &arm, world: &world, opening: 0.05, attached: None };
        // Gripper low on one side of the wall, then low on the other: the straight joint move
        // would sweep the hand through it.
        let start = [0.33, -0.55, 0.9, 0.0, 0.0, 0.0];
        let goal = [0.33, 0.55, -0.9, 0.0, 0.0, 0.0];
        assert!(
            world.segment_collision(&arm, &start, &goal, 0.05, None).is_some(),
            "the test needs a blocked straight line"
        );
        let path = problem.plan(&start, &goal, &PlannerParams::default(), 3).unwrap();
        assert!(path.len() > 2 && path[0] == start && *path.last().unwrap() == goal);
        let limits = Limits { velocity: arm.max_velocity(), acceleration: arm.max_acceleration() };
        let traj = Trajectory::piecewise(&path, &limits);
        let steps = (traj.duration() / 1e-3).ceil() as usize;
        let (lo, hi) = (arm.lower(), arm.upper());
        let mut prev_v = [0.0; 6];
        for i in 0..=steps {
            let (q, v) = traj.sample(i as f64 * 1e-3);
            assert_eq!(touches(&arm, &scene(), &q, 0.05), None, "at t = {} ms", i);
            for k in 0..6 {
                assert!(q[k] >= lo[k] - 1e-9 && q[k] <= hi[k] + 1e-9, "joint {k} out of its limits");
                assert!(v[k].abs() <= limits.velocity[k] * (1.0 + 1e-9), "joint {k} too fast");
                assert!(((v[k] - prev_v[k]) / 1e-3).abs() <= limits.acceleration[k] * (1.0 + 1e-6) + 1e-6);
            }
            prev_v = v;
        }
    }

    #[test]
    fn a_start_inside_an_obstacle_is_refused_with_the_parts_named() {
        let arm = umi();
        let world = CollisionWorld::new(&arm, scene(), 0.0);
        let problem = Problem { arm: &arm, world: &world, opening: 0.05, attached: None };
        let sunk = [0.2, 1.5, 0.5, 0.0, 0.0, 0.0]; // the tool 8.5 cm into the table, away from the wall
        let err = problem.plan(&sunk, &[0.5, 0.0, 0.5, 0.0, 0.0, 0.0], &PlannerParams::default(), 1).unwrap_err();
        assert!(matches!(err, PlanError::StartInCollision(_)), "{err}");
        assert!(err.to_string().contains("table"), "{err}");
    }

    #[test]
    fn a_held_object_is_checked_too() {
        let arm = umi();
        let world = CollisionWorld::new(&arm, scene(), 0.0);
        // Straight down, tool centre 10 cm over the table: free alone; a 30 cm long bar held
        // vertically reaches through the table.
        let q = [0.385, 0.3, 0.6, 0.0, 0.0, 0.0];
        assert_eq!(world.collision(&arm, &q, 0.05, None), None);
        let bar = Attached { shape: SharedShape::cuboid(0.01, 0.01, 0.15), gripper_from_shape: Isometry3::identity() };
        let hit = world.collision(&arm, &q, 0.05, Some(&bar)).expect("the bar reaches the table");
        assert_eq!((hit.part.as_str(), hit.obstacle.as_str()), ("held object", "table"));
    }
}
