//! The CPU renderer: what each CCD camera of the rig sees.
//!
//! Flat-shaded triangles (Lambertian + ambient, per-face albedo), z-buffered per sample, 16
//! samples per pixel on an n-rooks pattern (every sample has its own row and column of a
//! 16 x 16 sub-grid, so straight edges land at sub-pixel positions in 1/16 px steps), plus one
//! sample at the pixel centre for the depth and object-id maps. Gaussian sensor noise is seeded
//! per tile, so images do not depend on thread scheduling.
//!
//! Written by hand: the crates that rasterise either draw 2D paths without a z-buffer or need a
//! GPU, and this one must be exact about where an edge lands.

use crate::realism::Finish;
use mesh::{PinholeCamera, StereoCalibration, TriMesh};
use nalgebra::{Point3, Vector3};
use rand::{SeedableRng, rngs::Xoshiro256PlusPlus};
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;

/// Anti-aliasing samples per pixel (the depth/id sample comes on top).
pub const SAMPLES: usize = 16;
const TILE: usize = 32;
/// Near clipping plane, metres in front of the camera.
const NEAR: f64 = 0.01;
const NO_TRIANGLE: u32 = u32::MAX;

/// Sample offsets from the pixel centre: 16 n-rooks samples.
fn sample_offsets() -> ([f32; SAMPLES], [f32; SAMPLES]) {
    let (mut ox, mut oy) = ([0.0; SAMPLES], [0.0; SAMPLES]);
    for k in 0..SAMPLES {
        ox[k] = (k as f32 + 0.5) / SAMPLES as f32 - 0.5;
        oy[k] = (((5 * k + 3) % SAMPLES) as f32 + 0.5) / SAMPLES as f32 - 0.5;
    }
    (ox, oy)
}

/// The light of the scene; intensities as fractions of full white.
#[derive(Debug, Clone, Copy)]
pub struct Light {
    /// Unit vector from the scene towards the light.
    pub towards_light: Vector3<f64>,
    pub diffuse: f64,
    pub ambient: f64,
}

impl From<&crate::world::LightSpec> for Light {
    fn from(l: &crate::world::LightSpec) -> Self {
        Light { towards_light: Vector3::from(l.direction).normalize(), diffuse: l.diffuse, ambient: l.ambient }
    }
}

/// A world-space triangle ready to draw: corners, brightness (0-1) under the ideal light,
/// id-map value, and what the realistic renderer shades it from (albedo and finish).
#[derive(Debug, Clone, Copy)]
pub(crate) struct ShadedTriangle {
    pub(crate) corners: [Point3<f64>; 3],
    pub(crate) normal: Vector3<f64>,
    brightness: f32,
    pub(crate) id: u16,
    pub(crate) albedo: f32,
    pub(crate) finish: Finish,
}

/// Everything to draw, shaded once (Lambertian shading does not depend on the viewpoint).
/// Id-map value of the arm's `k`-th link (in the order `scene.json` lists them).
pub fn arm_link_id(k: usize) -> u32 {
    ARM_ID_BASE + k as u32
}

/// The arm's links have ids from here on; objects have ids from 1.
pub const ARM_ID_BASE: u32 = 1000;
/// Id-map value of the tool the gripper holds (the calibration flag).
pub const TOOL_ID: u32 = 999;

#[derive(Debug, Clone, Default)]
pub struct RenderScene {
    pub(crate) triangles: Vec<ShadedTriangle>,
}

impl RenderScene {
    /// Shades world-space meshes, each tagged with its id-map value.
    pub fn new(meshes: impl IntoIterator<Item = (u32, TriMesh)>, light: &Light) -> RenderScene {
        Self::with_finishes(meshes.into_iter().map(|(id, m)| (id, m, Finish::MATTE)), light)
    }

    /// Shades world-space meshes, each tagged with its id-map value and its surface's finish
    /// (which only the realistic renderer reads).
    pub fn with_finishes(meshes: impl IntoIterator<Item = (u32, TriMesh, Finish)>, light: &Light) -> RenderScene {
        let mut triangles = Vec::new();
        for (id, mesh, finish) in meshes {
            for t in 0..mesh.triangles.len() {
                let normal = mesh.face_normal(t);
                let lambert = normal.dot(&light.towards_light).max(0.0);
                let brightness = mesh.albedo[t] as f64 * (light.ambient + light.diffuse * lambert);
                triangles.push(ShadedTriangle {
                    corners: mesh.corners(t),
                    normal,
                    brightness: brightness.clamp(0.0, 1.0) as f32,
                    id: id as u16,
                    albedo: mesh.albedo[t],
                    finish,
                });
            }
        }
        RenderScene { triangles }
    }

    /// Every triangle's corners, in the world: what casts shadows.
    pub fn corners(&self) -> Vec<[Point3<f64>; 3]> {
        self.triangles.iter().map(|t| t.corners).collect()
    }
}

/// What one camera saw.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    pub width: usize,
    pub height: usize,
    /// 8-bit grey levels, row-major.
    pub image: Vec<u8>,
    /// Depth along the optical axis at each pixel centre, metres; 0 where nothing was hit.
    pub depth: Vec<f32>,
    /// Id-map value of the surface at each pixel centre (0 = fixed scenery or nothing).
    pub ids: Vec<u16>,
}

/// A triangle in pixel coordinates with its edge and inverse-depth planes.
#[derive(Debug, Clone, Copy)]
struct ScreenTriangle {
    /// Edge functions `a x + b y + c`, positive inside, in absolute pixel coordinates.
    edges: [[f64; 3]; 3],
    /// `1/z = p x + q y + r`.
    inv_z: [f64; 3],
    bbox: [i32; 4], // x0, y0, x1, y1 inclusive pixel range
    nearest_inv_z: f64,
    /// What the samples it covers keep: the ideal renderer's brightness, or, for the
    /// realistic renderer, the bits of `1 +` its index in the drawing order (0 is nothing).
    payload: f32,
    /// Its triangle in the [`RenderScene`].
    source: u32,
    id: u16,
}

/// Renders what `cam` sees of `scene`, with sensor noise of `noise_sigma` grey levels drawn
/// from `seed`.
pub fn render(scene: &RenderScene, cam: &PinholeCamera, noise_sigma: f64, seed: u64) -> Frame {
    let (w, h) = (cam.width as usize, cam.height as usize);
    let tris = project_sorted(scene, cam);
    let tiles = draw_tiles(&tris, w, h, |tris, area, pixels, k| {
        let tile_seed = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15).wrapping_add(k as u64);
        resolve(tris, area, pixels, noise_sigma, tile_seed)
    });
    let mut frame = Frame { width: w, height: h, image: vec![0; w * h], depth: vec![0.0; w * h], ids: vec![0; w * h] };
    for t in &tiles {
        for row in 0..t.area.h {
            let (src, dst) = (row * t.area.w, (t.area.y0 + row) * w + t.area.x0);
            frame.image[dst..dst + t.area.w].copy_from_slice(&t.image[src..src + t.area.w]);
            frame.depth[dst..dst + t.area.w].copy_from_slice(&t.depth[src..src + t.area.w]);
            frame.ids[dst..dst + t.area.w].copy_from_slice(&t.ids[src..src + t.area.w]);
        }
    }
    frame
}

/// The scene's triangles in `cam`'s pixels, nearest first (so that tiles learn early what
/// hides the rest, see [`draw_tile`]).
fn project_sorted(scene: &RenderScene, cam: &PinholeCamera) -> Vec<ScreenTriangle> {
    let mut tris = project(scene, cam);
    tris.sort_by(|a, b| b.nearest_inv_z.total_cmp(&a.nearest_inv_z));
    tris
}

/// Bins `tris` to tiles, draws each tile's samples and hands them to `resolve`, tile by tile
/// in parallel; returns what `resolve` made of each tile, in the tiles' order.
fn draw_tiles<T: Send>(
    tris: &[ScreenTriangle],
    w: usize,
    h: usize,
    resolve: impl Fn(&[ScreenTriangle], TileArea, &[PixelSamples], usize) -> T + Sync,
) -> Vec<T> {
    let (tiles_x, tiles_y) = (w.div_ceil(TILE), h.div_ceil(TILE));
    let mut bins: Vec<Vec<u32>> = vec![Vec::new(); tiles_x * tiles_y];
    for (i, t) in tris.iter().enumerate() {
        let [x0, y0, x1, y1] = t.bbox;
        for ty in y0 as usize / TILE..=y1 as usize / TILE {
            for tx in x0 as usize / TILE..=x1 as usize / TILE {
                bins[ty * tiles_x + tx].push(i as u32);
            }
        }
    }
    (0..tiles_x * tiles_y)
        .into_par_iter()
        .map_init(
            || vec![NOTHING; TILE * TILE],
            |pixels, k| {
                let (tx, ty) = (k % tiles_x, k / tiles_x);
                let area =
                    TileArea { x0: tx * TILE, y0: ty * TILE, w: TILE.min(w - tx * TILE), h: TILE.min(h - ty * TILE) };
                draw_tile(tris, &bins[k], area, pixels);
                resolve(tris, area, pixels, k)
            },
        )
        .collect()
}

/// What the virtual pinhole of a realistic camera saw: radiance (in brightness units) and, at
/// each pixel centre, the scene triangle there.
pub(crate) struct RadianceImage {
    pub(crate) width: usize,
    pub(crate) radiance: Vec<f32>,
    /// Per pixel, the drawn triangle at its centre (an index into `inv_z` and `ids`), or
    /// `u32::MAX` for nothing.
    pub(crate) centre: Vec<u32>,
    /// Per drawn triangle, the plane of inverse depth over the pixels: `1/z = p x + q y + r`.
    pub(crate) inv_z: Vec<[f64; 3]>,
    /// Per drawn triangle, its id-map value.
    pub(crate) ids: Vec<u16>,
}

/// Renders `scene` through `cam` as radiance, each pixel's covered samples grouped by the
/// triangle they see and each triangle shaded once, at the point of its plane on the ray
/// through the pixel's centre: `shade(triangle, world point)`. Only the pixels `needed` marks
/// are shaded (the rest keep radiance 0); the centre map is whole.
pub(crate) fn render_radiance<F: Fn(&ShadedTriangle, &Point3<f64>) -> f32 + Sync>(
    scene: &RenderScene,
    cam: &PinholeCamera,
    needed: &[bool],
    shade: &F,
) -> RadianceImage {
    let (w, h) = (cam.width as usize, cam.height as usize);
    let mut tris = project_sorted(scene, cam);
    for (i, t) in tris.iter_mut().enumerate() {
        t.payload = f32::from_bits(i as u32 + 1);
    }
    let tiles = draw_tiles(&tris, w, h, |tris, area, pixels, _| {
        resolve_radiance(scene, cam, tris, area, pixels, |p| needed[p], shade)
    });
    let mut out = RadianceImage {
        width: w,
        radiance: vec![0.0; w * h],
        centre: vec![u32::MAX; w * h],
        inv_z: tris.iter().map(|t| t.inv_z).collect(),
        ids: tris.iter().map(|t| t.id).collect(),
    };
    for (area, radiance, centre) in &tiles {
        for row in 0..area.h {
            let (src, dst) = (row * area.w, (area.y0 + row) * w + area.x0);
            out.radiance[dst..dst + area.w].copy_from_slice(&radiance[src..src + area.w]);
            out.centre[dst..dst + area.w].copy_from_slice(&centre[src..src + area.w]);
        }
    }
    out
}

/// One tile's radiance: each pixel's samples counted by triangle, each triangle shaded once.
fn resolve_radiance<F: Fn(&ShadedTriangle, &Point3<f64>) -> f32 + Sync>(
    scene: &RenderScene,
    cam: &PinholeCamera,
    tris: &[ScreenTriangle],
    area: TileArea,
    pixels: &[PixelSamples],
    needed: impl Fn(usize) -> bool,
    shade: &F,
) -> (TileArea, Vec<f32>, Vec<u32>) {
    let n = area.w * area.h;
    let (mut radiance, mut centre) = (vec![0.0f32; n], vec![u32::MAX; n]);
    let eye = cam.centre();
    let world_from_cam = cam.world_from_cam.rotation.to_rotation_matrix();
    let (inv_fx, inv_fy) = (1.0 / cam.fx, 1.0 / cam.fy);
    let offsets = sample_offsets();
    for (p, px) in pixels.iter().enumerate() {
        if px.centre != NO_TRIANGLE {
            centre[p] = px.centre;
        }
        let (col, row) = (area.x0 + p % area.w, area.y0 + p / area.w);
        if !needed(row * cam.width as usize + col) {
            continue;
        }
        let (u, v) = (col as f64, row as f64);
        let (x, y) = ((u - cam.cx) * inv_fx, (v - cam.cy) * inv_fy);
        // Each triangle seen: its samples' count and the sum of their offsets from the centre.
        let mut seen: [(u32, u32, f32, f32); SAMPLES] = [(0, 0, 0.0, 0.0); SAMPLES];
        let mut kinds = 0;
        let first = px.shade[0].to_bits();
        if px.shade.iter().all(|s| s.to_bits() == first) {
            // The common case, a pixel wholly inside one triangle (or seeing nothing).
            if first != 0 {
                seen[0] = (first, SAMPLES as u32, 0.0, 0.0);
                kinds = 1;
            }
        } else {
            for (k, s) in px.shade.iter().enumerate() {
                let bits = s.to_bits();
                if bits == 0 {
                    continue;
                }
                match seen[..kinds].iter_mut().find(|(b, ..)| *b == bits) {
                    Some((_, count, sx, sy)) => {
                        *count += 1;
                        *sx += offsets.0[k];
                        *sy += offsets.1[k];
                    }
                    None => {
                        seen[kinds] = (bits, 1, offsets.0[k], offsets.1[k]);
                        kinds += 1;
                    }
                }
            }
        }
        let mut sum = 0.0f32;
        for &(bits, count, sx, sy) in &seen[..kinds] {
            let drawn = &tris[bits as usize - 1];
            let t = &scene.triangles[drawn.source as usize];
            // Shaded where the ray through the middle of its own samples meets its plane (at
            // the depth the plane of `1/z` over the pixels gives): for a pixel it only partly
            // covers, on the part it shows. The pixel's centre may lie on what hides it, and the
            // plane there under that thing, in its shadow.
            let (du, dv) = ((sx / count as f32) as f64, (sy / count as f32) as f64);
            let [a, b, c] = drawn.inv_z;
            let z = 1.0 / (a * (u + du) + b * (v + dv) + c);
            let point = if z.is_finite() && z > 0.0 {
                let (x, y) = (x + du * inv_fx, y + dv * inv_fy);
                eye + world_from_cam * Vector3::new(x * z, y * z, z)
            } else {
                t.corners[0]
            };
            sum += count as f32 * shade(t, &point);
        }
        radiance[p] = sum / SAMPLES as f32;
    }
    (area, radiance, centre)
}

/// Renders both cameras of the rig at once; the right camera's noise uses the next seed.
pub fn render_stereo(scene: &RenderScene, calib: &StereoCalibration, noise_sigma: f64, seed: u64) -> (Frame, Frame) {
    rayon::join(
        || render(scene, &calib.left, noise_sigma, seed.wrapping_mul(2)),
        || render(scene, &calib.right, noise_sigma, seed.wrapping_mul(2).wrapping_add(1)),
    )
}

/// Moves triangles into the camera, drops those facing away, clips at the near plane and
/// sets up the edge and depth planes of each piece.
fn project(scene: &RenderScene, cam: &PinholeCamera) -> Vec<ScreenTriangle> {
    let cam_from_world = cam.cam_from_world();
    let centre = cam.centre();
    let mut out = Vec::with_capacity(scene.triangles.len());
    for (source, t) in scene.triangles.iter().enumerate() {
        if t.normal.dot(&(t.corners[0] - centre)) >= 0.0 {
            continue; // seen from behind: a closed solid's far side
        }
        let corners = t.corners.map(|p| cam_from_world * p);
        if corners.iter().all(|p| p.z < NEAR) {
            continue;
        }
        let polygon = clip_near(&corners, NEAR);
        let pixels: Vec<[f64; 3]> =
            polygon.iter().map(|p| [cam.fx * p.x / p.z + cam.cx, cam.fy * p.y / p.z + cam.cy, 1.0 / p.z]).collect();
        for k in 1..pixels.len().saturating_sub(1) {
            if let Some(s) = setup([pixels[0], pixels[k], pixels[k + 1]], cam, t, source as u32) {
                out.push(s);
            }
        }
    }
    out
}

/// Clips a camera-space triangle to `z >= near` (Sutherland-Hodgman against one plane).
pub(crate) fn clip_near(tri: &[Point3<f64>; 3], near: f64) -> Vec<Point3<f64>> {
    let mut out = Vec::with_capacity(4);
    for i in 0..3 {
        let (a, b) = (tri[i], tri[(i + 1) % 3]);
        if a.z >= near {
            out.push(a);
        }
        if (a.z >= near) != (b.z >= near) {
            let s = (near - a.z) / (b.z - a.z);
            out.push(a + (b - a) * s);
        }
    }
    out
}

/// The edge functions `a x + b y + c` of a triangle whose first two coordinates are pixels,
/// positive inside whichever way it winds (`area2` is twice its signed area).
pub(crate) fn edge_functions<const N: usize>(v: &[[f64; N]; 3], area2: f64) -> [[f64; 3]; 3] {
    let sign = area2.signum();
    [0, 1, 2].map(|i| {
        let (p, q) = (v[i], v[(i + 1) % 3]);
        let (a, b) = (-(q[1] - p[1]) * sign, (q[0] - p[0]) * sign);
        [a, b, -(a * p[0] + b * p[1])]
    })
}

/// The plane `[p, q, r]` of the third coordinate (`1/z`) over the pixels: `p x + q y + r`.
pub(crate) fn inv_z_plane(v: &[[f64; 3]; 3], area2: f64) -> [f64; 3] {
    let (dx1, dy1, dz1) = (v[1][0] - v[0][0], v[1][1] - v[0][1], v[1][2] - v[0][2]);
    let (dx2, dy2, dz2) = (v[2][0] - v[0][0], v[2][1] - v[0][1], v[2][2] - v[0][2]);
    let p = (dz1 * dy2 - dz2 * dy1) / area2;
    let q = (dx1 * dz2 - dx2 * dz1) / area2;
    [p, q, v[0][2] - p * v[0][0] - q * v[0][1]]
}

/// Twice the signed area of a triangle in its first two coordinates.
pub(crate) fn area2<const N: usize>(v: &[[f64; N]; 3]) -> f64 {
    (v[1][0] - v[0][0]) * (v[2][1] - v[0][1]) - (v[2][0] - v[0][0]) * (v[1][1] - v[0][1])
}

/// The run `[lo, hi]` of whole `x` in `0..=last` where every edge function is at least 0 along
/// row `y`, each point taken at `x + offset`; `None` where there is none.
pub(crate) fn run_along_row(edges: &[[f64; 3]; 3], y: f64, offset: f64, last: f64) -> Option<(usize, usize)> {
    let (mut lo, mut hi) = (0.0f64, last);
    for [a, b, c] in edges {
        let rest = b * y + c;
        if *a > 0.0 {
            lo = lo.max((-rest / a - offset).ceil());
        } else if *a < 0.0 {
            hi = hi.min((-rest / a - offset).floor());
        } else if rest < 0.0 {
            return None;
        }
    }
    (lo <= hi).then_some((lo as usize, hi as usize))
}

fn setup(v: [[f64; 3]; 3], cam: &PinholeCamera, t: &ShadedTriangle, source: u32) -> Option<ScreenTriangle> {
    let area2 = area2(&v);
    if area2.abs() < 1e-12 {
        return None;
    }
    let edges = edge_functions(&v, area2);
    let [p, q, r] = inv_z_plane(&v, area2);
    let (minx, maxx) =
        (v.iter().map(|c| c[0]).fold(f64::MAX, f64::min), v.iter().map(|c| c[0]).fold(f64::MIN, f64::max));
    let (miny, maxy) =
        (v.iter().map(|c| c[1]).fold(f64::MAX, f64::min), v.iter().map(|c| c[1]).fold(f64::MIN, f64::max));
    let bbox = [
        ((minx - 0.5).ceil() as i64).max(0),
        ((miny - 0.5).ceil() as i64).max(0),
        ((maxx + 0.5).floor() as i64).min(cam.width as i64 - 1),
        ((maxy + 0.5).floor() as i64).min(cam.height as i64 - 1),
    ];
    if bbox[0] > bbox[2] || bbox[1] > bbox[3] {
        return None;
    }
    let nearest_inv_z = v.iter().map(|c| c[2]).fold(f64::MIN, f64::max);
    Some(ScreenTriangle {
        edges,
        inv_z: [p, q, r],
        bbox: bbox.map(|c| c as i32),
        nearest_inv_z,
        payload: t.brightness,
        source,
        id: t.id,
    })
}

#[derive(Debug, Clone, Copy)]
pub(crate) struct TileArea {
    x0: usize,
    y0: usize,
    w: usize,
    h: usize,
}

struct TileOut {
    area: TileArea,
    image: Vec<u8>,
    depth: Vec<f32>,
    ids: Vec<u16>,
}

/// The samples of one pixel: the anti-aliasing samples keep the brightness of the nearest
/// surface; the centre sample keeps its triangle, for the depth and id maps.
#[derive(Debug, Clone, Copy)]
struct PixelSamples {
    inv_z: [f32; SAMPLES],
    shade: [f32; SAMPLES],
    centre_inv_z: f32,
    centre: u32,
}

const NOTHING: PixelSamples =
    PixelSamples { inv_z: [0.0; SAMPLES], shade: [0.0; SAMPLES], centre_inv_z: 0.0, centre: NO_TRIANGLE };

/// One triangle's planes relative to a tile's origin, with every sample's offset from the
/// pixel centre already applied to each plane.
struct TilePlanes {
    edges: [[f32; 3]; 3],
    inv_z: [f32; 3],
    /// Half the range of each edge function over a pixel: beyond it, all samples agree.
    reach: [f32; 3],
    edge_at_sample: [[f32; SAMPLES]; 3],
    inv_z_at_sample: [f32; SAMPLES],
}

impl TilePlanes {
    fn new(t: &ScreenTriangle, area: &TileArea, (ox, oy): &([f32; SAMPLES], [f32; SAMPLES])) -> Self {
        // Planes relative to the tile origin keep f32 exact enough.
        let (x0, y0) = (area.x0 as f64, area.y0 as f64);
        let rel = |[a, b, c]: [f64; 3]| [a as f32, b as f32, (c + a * x0 + b * y0) as f32];
        let edges = t.edges.map(rel);
        let inv_z = rel(t.inv_z);
        let at_samples = |[a, b, _]: [f32; 3]| std::array::from_fn(|s| a * ox[s] + b * oy[s]);
        TilePlanes {
            reach: edges.map(|[a, b, _]| 0.5 * (a.abs() + b.abs())),
            edge_at_sample: edges.map(at_samples),
            inv_z_at_sample: at_samples(inv_z),
            edges,
            inv_z,
        }
    }

    fn inv_z_at(&self, x: f32, y: f32) -> f32 {
        self.inv_z[0] * x + self.inv_z[1] * y + self.inv_z[2]
    }
}

/// Rasterises the triangles binned to one tile (nearest first) into its samples. Once a triangle has covered the whole tile, any later one lying wholly behind it is
/// skipped: that is what keeps the hidden floor under the table from costing a full pass.
fn draw_tile(tris: &[ScreenTriangle], binned: &[u32], area: TileArea, pixels: &mut Vec<PixelSamples>) {
    let offsets = sample_offsets();
    pixels.clear();
    pixels.resize(area.w * area.h, NOTHING);
    // Every sample of the tile is known to be at least this near (in 1/z).
    let mut occluded_beyond = 0.0f32;
    let (right, bottom) = (area.w as f32 - 0.5, area.h as f32 - 0.5);
    let corners = [(-0.5, -0.5), (right, -0.5), (-0.5, bottom), (right, bottom)];
    for &ti in binned {
        let t = &tris[ti as usize];
        let pl = TilePlanes::new(t, &area, &offsets);
        let corner_z = corners.map(|(x, y)| pl.inv_z_at(x, y));
        if corner_z.iter().all(|&z| z < occluded_beyond) {
            continue;
        }
        let edge_at_corners = pl.edges.map(|[a, b, c]| corners.map(|(x, y)| a * x + b * y + c));
        if edge_at_corners.iter().any(|e| e.iter().all(|&v| v < 0.0)) {
            continue; // the tile lies wholly outside one edge
        }
        let covers_tile = edge_at_corners.iter().all(|e| e.iter().all(|&v| v >= 0.0));
        rasterise(pixels, t, ti, &pl, &area, covers_tile);
        if covers_tile {
            occluded_beyond = occluded_beyond.max(corner_z.into_iter().fold(f32::MAX, f32::min));
        }
    }
}

/// Draws one triangle into a tile's samples; `whole` when it covers every sample of the tile.
fn rasterise(pixels: &mut [PixelSamples], t: &ScreenTriangle, ti: u32, pl: &TilePlanes, area: &TileArea, whole: bool) {
    let xs = (t.bbox[0] as usize).max(area.x0)..=(t.bbox[2] as usize).min(area.x0 + area.w - 1);
    let ys = (t.bbox[1] as usize).max(area.y0)..=(t.bbox[3] as usize).min(area.y0 + area.h - 1);
    for py in ys {
        let y = (py - area.y0) as f32;
        for px in xs.clone() {
            let x = (px - area.x0) as f32;
            let zc = pl.inv_z_at(x, y);
            let p = &mut pixels[(py - area.y0) * area.w + (px - area.x0)];
            if whole {
                cover_all(p, zc, &pl.inv_z_at_sample, t.payload);
                if zc > p.centre_inv_z {
                    p.centre_inv_z = zc;
                    p.centre = ti;
                }
                continue;
            }
            let ec = pl.edges.map(|[a, b, c]| a * x + b * y + c);
            if (0..3).any(|i| ec[i] < -pl.reach[i]) {
                continue;
            }
            if (0..3).all(|i| ec[i] >= pl.reach[i]) {
                cover_all(p, zc, &pl.inv_z_at_sample, t.payload);
            } else {
                cover_some(p, zc, pl, ec, t.payload);
            }
            if ec.iter().all(|&e| e >= 0.0) && zc > p.centre_inv_z {
                p.centre_inv_z = zc;
                p.centre = ti;
            }
        }
    }
}

/// Depth-tests every anti-aliasing sample of a pixel the triangle covers entirely.
#[inline(always)]
fn cover_all(p: &mut PixelSamples, zc: f32, dz: &[f32; SAMPLES], shade: f32) {
    let zs: [f32; SAMPLES] = std::array::from_fn(|s| zc + dz[s]);
    keep_nearer(p, &zs, &[true; SAMPLES], shade);
}

/// Depth-tests the anti-aliasing samples of a pixel that the triangle covers.
#[inline(always)]
fn cover_some(p: &mut PixelSamples, zc: f32, pl: &TilePlanes, ec: [f32; 3], shade: f32) {
    let [e0, e1, e2] = &pl.edge_at_sample;
    let inside: [bool; SAMPLES] =
        std::array::from_fn(|s| (ec[0] + e0[s] >= 0.0) & (ec[1] + e1[s] >= 0.0) & (ec[2] + e2[s] >= 0.0));
    let zs: [f32; SAMPLES] = std::array::from_fn(|s| zc + pl.inv_z_at_sample[s]);
    keep_nearer(p, &zs, &inside, shade);
}

/// Where a covered sample is nearer than what the pixel holds, takes its depth and shade.
/// Written as whole-array selects on bits, not conditional stores, so that it vectorises.
#[inline(always)]
fn keep_nearer(p: &mut PixelSamples, zs: &[f32; SAMPLES], inside: &[bool; SAMPLES], shade: f32) {
    let mask: [u32; SAMPLES] = std::array::from_fn(|s| if inside[s] & (zs[s] > p.inv_z[s]) { u32::MAX } else { 0 });
    let pick = |new: f32, old: f32, m: u32| f32::from_bits((new.to_bits() & m) | (old.to_bits() & !m));
    p.inv_z = std::array::from_fn(|s| pick(zs[s], p.inv_z[s], mask[s]));
    p.shade = std::array::from_fn(|s| pick(shade, p.shade[s], mask[s]));
}

fn resolve(tris: &[ScreenTriangle], area: TileArea, pixels: &[PixelSamples], noise_sigma: f64, seed: u64) -> TileOut {
    let n = area.w * area.h;
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let noise = Normal::new(0.0f32, noise_sigma as f32).expect("noise sigma is checked to be >= 0");
    let mut out = TileOut { area, image: vec![0; n], depth: vec![0.0; n], ids: vec![0; n] };
    for (p, px) in pixels.iter().enumerate() {
        let sum: f32 = px.shade.iter().sum();
        let grain = if noise_sigma > 0.0 { noise.sample(&mut rng) } else { 0.0 };
        // Clamped to 0-255 first, so adding 0.5 and truncating rounds to nearest.
        out.image[p] = ((255.0 * sum / SAMPLES as f32 + grain).clamp(0.0, 255.0) + 0.5) as u8;
        if px.centre != NO_TRIANGLE {
            out.depth[p] = 1.0 / px.centre_inv_z;
            out.ids[p] = tris[px.centre as usize].id;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    fn overhead_camera() -> PinholeCamera {
        PinholeCamera::looking_at(
            (64, 64),
            100.0,
            [31.5, 31.5],
            Point3::new(0.0, 0.0, 1.0),
            Point3::origin(),
            Vector3::y(),
        )
    }

    #[test]
    fn n_rooks_samples_cover_every_row_and_column_once() {
        let (ox, oy) = sample_offsets();
        let mut rows: Vec<i32> = oy[..SAMPLES].iter().map(|o| ((o + 0.5) * 16.0).floor() as i32).collect();
        let mut cols: Vec<i32> = ox[..SAMPLES].iter().map(|o| ((o + 0.5) * 16.0).floor() as i32).collect();
        rows.sort();
        cols.sort();
        assert_eq!(rows, (0..16).collect::<Vec<_>>());
        assert_eq!(cols, (0..16).collect::<Vec<_>>());
    }

    #[test]
    fn edges_land_at_their_sub_pixel_positions() {
        // A flat white square seen from straight above: image u runs along world x, and the
        // square spans u from 41.3 to 61.5 (x from 0.098 to 0.3 m at 1 m, f = 100 px).
        let square = TriMesh::cuboid(Vector3::new(0.101, 0.1, 1e-7), 1.0)
            .transformed(&nalgebra::Isometry3::translation(0.199, 0.0, 0.0));
        let light = Light { towards_light: Vector3::z(), diffuse: 0.0, ambient: 1.0 };
        let scene = RenderScene::new([(1, square)], &light);
        let f = render(&scene, &overhead_camera(), 0.0, 0);
        let row = 32 * 64;
        let total: f64 = (0..64).map(|u| f.image[row + u] as f64 / 255.0).sum();
        // Summed coverage along a row is the covered length, to 1/16 px per edge.
        assert!((total - 20.2).abs() < 2.0 / 16.0, "covered {total} px of the row, expected 20.2");
        assert_eq!(f.image[row + 50], 255);
        assert_eq!(f.image[row + 20], 0);
    }

    #[test]
    fn depth_is_along_the_optical_axis_and_ids_mark_objects() {
        let plate = TriMesh::cuboid(Vector3::new(1.0, 1.0, 0.01), 0.5)
            .transformed(&nalgebra::Isometry3::translation(0.0, 0.0, -0.01));
        let light = Light { towards_light: Vector3::z(), diffuse: 1.0, ambient: 0.0 };
        let scene = RenderScene::new([(7, plate)], &light);
        let f = render(&scene, &overhead_camera(), 0.0, 0);
        for p in [0, 64 * 32 + 5, 64 * 64 - 1] {
            assert!((f.depth[p] - 1.0).abs() < 1e-5, "depth {}", f.depth[p]);
            assert_eq!(f.ids[p], 7);
            assert_eq!(f.image[p], 128); // albedo 0.5, full light
        }
    }

    #[test]
    fn noise_has_the_asked_spread_and_follows_the_seed() {
        let plate = TriMesh::cuboid(Vector3::new(1.0, 1.0, 0.01), 0.5);
        let light = Light { towards_light: Vector3::z(), diffuse: 1.0, ambient: 0.0 };
        let scene = RenderScene::new([(1, plate)], &light);
        let cam = overhead_camera();
        let (a, b, c) = (render(&scene, &cam, 1.5, 3), render(&scene, &cam, 1.5, 3), render(&scene, &cam, 1.5, 4));
        assert_eq!(a, b);
        assert_ne!(a.image, c.image);
        let mean = 255.0 * 0.5;
        let var = a.image.iter().map(|&g| (g as f64 - mean).powi(2)).sum::<f64>() / a.image.len() as f64;
        // Rounding to integers adds 1/12 to the variance.
        assert!((var.sqrt() - (1.5f64.powi(2) + 1.0 / 12.0).sqrt()).abs() < 0.1, "sigma {}", var.sqrt());
    }
}
