//! Time-parameterised joint trajectories within velocity and acceleration limits.
//!
//! A trajectory is a sequence of strokes. A stroke is a joint-space polyline followed at rest to
//! rest under one trapezoidal speed profile along its normalised arc length, scaled so that no
//! joint exceeds its velocity or acceleration limit on any piece. A planner's path becomes one
//! stroke per segment: it stops at corners, so it never leaves the checked straight segments and
//! no joint velocity jumps.

use crate::arm::Joints;

/// A rest-to-rest move along a polyline.
#[derive(Debug, Clone)]
struct Stroke {
    points: Vec<Joints>,
    /// Cumulative normalised length at each point (0 .. 1).
    at: Vec<f64>,
    /// Limits on the normalised path speed and acceleration.
    speed: f64,
    accel: f64,
    t_acc: f64,
    duration: f64,
}

/// A time-parameterised trajectory.
#[derive(Debug, Clone, Default)]
pub struct Trajectory {
    strokes: Vec<Stroke>,
    starts: Vec<f64>,
}

/// Joint-space velocity and acceleration limits, with a speed fraction (1 = full speed).
#[derive(Debug, Clone, Copy)]
pub struct Limits {
    pub velocity: Joints,
    pub acceleration: Joints,
}

impl Limits {
    pub fn scaled(&self, fraction: f64) -> Limits {
        Limits { velocity: self.velocity.map(|v| v * fraction), acceleration: self.acceleration.map(|a| a * fraction) }
    }
}

impl Trajectory {
    /// One rest-to-rest stroke per consecutive pair of `path` points.
    pub fn piecewise(path: &[Joints], limits: &Limits) -> Trajectory {
        let mut t = Trajectory::default();
        for pair in path.windows(2) {
            t.push_stroke(pair, limits);
        }
        t
    }

    /// Appends a rest-to-rest stroke through `points`; a stroke of zero length is skipped.
    /// The profile bounds each joint's speed and acceleration along every piece; at an interior
    /// corner the joint velocities turn abruptly, so multi-point strokes suit only nearly
    /// straight polylines. The planner's paths use [`Trajectory::piecewise`].
    fn push_stroke(&mut self, points: &[Joints], limits: &Limits) {
        let lengths: Vec<f64> = points.windows(2).map(|w| max_norm(&w[0], &w[1])).collect();
        let total: f64 = lengths.iter().sum();
        if points.len() < 2 || total < 1e-12 {
            return;
        }
        let mut at = vec![0.0];
        let (mut speed, mut accel) = (f64::INFINITY, f64::INFINITY);
        for (w, len) in points.windows(2).zip(&lengths) {
            at.push(at.last().unwrap() + len / total);
            let ds = len / total;
            if ds <= 0.0 {
                continue;
            }
            let (from, to) = (&w[0], &w[1]);
            for ((a, b), (v_max, a_max)) in from.iter().zip(to).zip(limits.velocity.iter().zip(&limits.acceleration)) {
                // dq/ds on this piece; the path speed must keep |dq/dt| within the limits.
                let slope = (b - a).abs() / ds;
                if slope > 0.0 {
                    speed = speed.min(v_max / slope);
                    accel = accel.min(a_max / slope);
                }
            }
        }
        *at.last_mut().unwrap() = 1.0;
        let (t_acc, duration) = if speed * speed / accel >= 1.0 {
            let t_acc = (1.0 / accel).sqrt();
            (t_acc, 2.0 * t_acc)
        } else {
            let t_acc = speed / accel;
            (t_acc, 2.0 * t_acc + (1.0 - speed * t_acc) / speed)
        };
        let speed = speed.min(accel * t_acc);
        self.starts.push(self.duration());
        self.strokes.push(Stroke { points: points.to_vec(), at, speed, accel, t_acc, duration });
    }

    pub fn duration(&self) -> f64 {
        self.strokes.last().map_or(0.0, |s| self.starts.last().unwrap() + s.duration)
    }

    pub fn is_empty(&self) -> bool {
        self.strokes.is_empty()
    }

    /// The last configuration, if any.
    pub fn end(&self) -> Option<Joints> {
        self.strokes.last().map(|s| *s.points.last().unwrap())
    }

    /// Every polyline point, in order (the path the trajectory follows).
    pub fn points(&self) -> impl Iterator<Item = &Joints> {
        self.strokes.iter().flat_map(|s| s.points.iter())
    }

    /// Position and velocity at time `t` (clamped to the trajectory).
    pub fn sample(&self, t: f64) -> (Joints, Joints) {
        let i = self.starts.partition_point(|&s| s <= t).saturating_sub(1);
        let stroke = &self.strokes[i];
        stroke.sample((t - self.starts[i]).clamp(0.0, stroke.duration))
    }
}

impl Stroke {
    /// Normalised position and speed along the stroke at local time `t`.
    fn profile(&self, t: f64) -> (f64, f64) {
        let (a, v, ta, d) = (self.accel, self.speed, self.t_acc, self.duration);
        if t < ta {
            (0.5 * a * t * t, a * t)
        } else if t > d - ta {
            let r = d - t;
            (1.0 - 0.5 * a * r * r, a * r)
        } else {
            (0.5 * a * ta * ta + v * (t - ta), v)
        }
    }

    fn sample(&self, t: f64) -> (Joints, Joints) {
        let (s, ds) = self.profile(t);
        let s = s.clamp(0.0, 1.0);
        let j = self.at.partition_point(|&x| x <= s).clamp(1, self.points.len() - 1);
        let (a, b) = (&self.points[j - 1], &self.points[j]);
        let span = self.at[j] - self.at[j - 1];
        let u = if span > 0.0 { (s - self.at[j - 1]) / span } else { 1.0 };
        let q = std::array::from_fn(|k| a[k] + u * (b[k] - a[k]));
        let qd = std::array::from_fn(|k| if span > 0.0 { (b[k] - a[k]) / span * ds } else { 0.0 });
        (q, qd)
    }
}

/// The largest single-joint change (the stroke's arc length measure; any norm would do, this one
/// keeps the slopes at most 1).
fn max_norm(a: &Joints, b: &Joints) -> f64 {
    (0..6).map(|k| (a[k] - b[k]).abs()).fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limits() -> Limits {
        let velocity = [0.25, 1.5, 2.0, 3.0, 3.0, 4.0];
        Limits { velocity, acceleration: velocity.map(|v| v * 4.0) }
    }

    /// Samples every millisecond: positions continuous, endpoints hit, velocities and (finite
    /// difference) accelerations within limits.
    fn check(traj: &Trajectory, points: &[Joints], lim: &Limits) {
        let dt = 1e-3;
        let n = (traj.duration() / dt).ceil() as usize;
        let mut prev_v = [0.0; 6];
        for i in 0..=n {
            let (q, v) = traj.sample(i as f64 * dt);
            for k in 0..6 {
                assert!(v[k].abs() <= lim.velocity[k] * (1.0 + 1e-9), "joint {k} speed {} at step {i}", v[k]);
                let acc = (v[k] - prev_v[k]) / dt;
                assert!(acc.abs() <= lim.acceleration[k] * (1.0 + 1e-6) + 1e-6, "joint {k} accel {acc} at {i}");
            }
            prev_v = v;
            if i == 0 {
                assert_eq!(q, points[0]);
            }
        }
        let (end, v_end) = traj.sample(traj.duration());
        assert!(max_norm(&end, points.last().unwrap()) < 1e-12 && v_end.iter().all(|v| v.abs() < 1e-9));
    }

    #[test]
    fn piecewise_strokes_respect_limits_and_reach_each_waypoint() {
        let lim = limits();
        let path = [[0.3, 0.0, 0.0, 0.0, 0.0, 0.0], [0.5, 1.0, -0.5, 0.2, 0.1, 0.0], [0.5, 1.02, -0.5, 0.2, 0.1, 2.0]];
        let traj = Trajectory::piecewise(&path, &lim);
        check(&traj, &path, &lim);
        // Rest at the corner: the second waypoint is passed with zero velocity.
        let corner = traj.starts[1];
        let (q, v) = traj.sample(corner);
        assert!(max_norm(&q, &path[1]) < 1e-12 && v.iter().all(|v| v.abs() < 1e-9));
    }
}
