//! The board's corners in one image: found and labelled by `calib-targets` (ChESS corners
//! assembled into a grid), each refined by `chess-corners`' saddle-point refiner (a quadratic
//! surface fitted to the image around the corner). On the cell's realistic renders the
//! refined corners lie 0.03 px from the truth (median; the crate's default centre-of-mass
//! localiser 0.17 px, OpenCV's `cornerSubPix` 0.04 px on the same image).
//!
//! The grid's labels are turned into the board's own: only the whole board is used (its
//! corner count fixes which way round the grid lies up to a half turn) and the half turn is
//! read from the squares' colours. A view is dropped, with the reason, when the board is not
//! found, partly out of view or hidden, too blurred or too oblique.

use crate::board::Board;
use calib_targets::chessboard::ChessboardParams;
use chess_corners::ImageRefiner;
use image::GrayImage;
use nalgebra::{Point2, Vector2};
use std::collections::HashMap;

/// The widest edge blur accepted (the Gaussian sigma of the squares' edges, pixels): beyond
/// it the saddle fit's window sees more blur than corner.
pub const MAX_BLUR_SIGMA_PX: f64 = 2.5;
/// The least ratio of a square's shorter side to its longer one in the image (the cosine of
/// the tilt, near enough): boards seen more obliquely locate their corners poorly along the
/// foreshortened direction.
pub const MIN_FORESHORTENING: f64 = 0.4;
/// The least difference in grey level between the light and dark squares.
pub const MIN_CONTRAST: f64 = 20.0;

/// Why a view gave no corners.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Dropped {
    #[error("board not found")]
    NotFound,
    #[error("board partly out of view or hidden: {found} of {expected} corners found")]
    Partial { found: usize, expected: usize },
    #[error("the grid found ({found} corners) holds more than one place the board could be")]
    Unclear { found: usize },
    #[error("too blurred: the squares' edges spread {sigma_px:.1} px (at most {MAX_BLUR_SIGMA_PX} px)")]
    Blurred { sigma_px: f64 },
    #[error("too oblique: the squares are foreshortened to {ratio:.2} of their width (at least {MIN_FORESHORTENING})")]
    Oblique { ratio: f64 },
    #[error("too little contrast: {contrast:.0} grey levels between the squares (at least {MIN_CONTRAST})")]
    LowContrast { contrast: f64 },
}

/// The board's inner corners in `image`, in [`Board::points`]'s order (pixels, pixel centres
/// at integer coordinates), or why the view is dropped.
pub fn detect(image: &GrayImage, board: &Board) -> Result<Vec<Point2<f64>>, Dropped> {
    let mut cfg = calib_targets::detect::default_chess_config();
    cfg.refiner = Some(ImageRefiner::saddle_point());
    let found = calib_targets::detect::detect_chessboard(image, &cfg, &ChessboardParams::default())
        .map_err(|_| Dropped::NotFound)?;
    let labelled: HashMap<(i32, i32), Point2<f64>> = found
        .corners
        .iter()
        .map(|c| ((c.grid.u, c.grid.v), Point2::new(c.position.x as f64, c.position.y as f64)))
        .collect();
    let corners = board_order(&labelled, board, image)?;
    check_shape(&corners, board)?;
    check_sharpness(&corners, board, image)?;
    Ok(corners)
}

/// A board corner's `(i, j)` to the detected grid's `(u, v)`.
type Turn = Box<dyn Fn(i32, i32) -> (i32, i32)>;

/// The grid's corners in the board's order: the grid rebased to start at `(0, 0)`, turned a
/// quarter turn if it lies the other way, and a half turn if the squares' colours say so.
fn board_order(
    labelled: &HashMap<(i32, i32), Point2<f64>>,
    board: &Board,
    image: &GrayImage,
) -> Result<Vec<Point2<f64>>, Dropped> {
    let [nx, ny] = board.inner();
    let partial = || Dropped::Partial { found: labelled.len(), expected: nx * ny };
    if labelled.len() < nx * ny {
        return Err(partial());
    }
    // The board's corners are the one whole nx x ny (or ny x nx) window of the grid: a stray
    // corner beside it (a finger's edge on the margin) is left out.
    let windows: Vec<((i32, i32), (usize, usize))> = [(nx, ny), (ny, nx)]
        .into_iter()
        .flat_map(|span| labelled.keys().map(move |&origin| (origin, span)))
        .filter(|&((u0, v0), (w, h))| {
            (0..h as i32).all(|dv| (0..w as i32).all(|du| labelled.contains_key(&(u0 + du, v0 + dv))))
        })
        .collect();
    let [((u0, v0), span)] = windows[..] else {
        return Err(if windows.is_empty() { partial() } else { Dropped::Unclear { found: labelled.len() } });
    };
    let (nxi, nyi) = (nx as i32, ny as i32);
    // Board (i, j) -> grid (u, v), for the two turns that fit the grid's shape (both keep the
    // image's handedness: the board is seen from its printed face).
    let turns: [Turn; 2] = if span == (nx, ny) {
        [Box::new(|i, j| (i, j)), Box::new(move |i, j| (nxi - 1 - i, nyi - 1 - j))]
    } else if span == (ny, nx) {
        [Box::new(move |i, j| (nyi - 1 - j, i)), Box::new(move |i, j| (j, nxi - 1 - i))]
    } else {
        return Err(partial());
    };
    let order = |turn: &dyn Fn(i32, i32) -> (i32, i32)| -> Option<Vec<Point2<f64>>> {
        (0..nyi)
            .flat_map(|j| (0..nxi).map(move |i| (i, j)))
            .map(|(i, j)| {
                let (u, v) = turn(i, j);
                labelled.get(&(u + u0, v + v0)).copied()
            })
            .collect()
    };
    let first = order(&*turns[0]).ok_or_else(partial)?;
    if colour_agreement(&first, board, image) >= 0.0 { Ok(first) } else { order(&*turns[1]).ok_or_else(partial) }
}

/// Bilinear grey level at `p`.
fn sample(image: &GrayImage, p: Point2<f64>) -> f64 {
    let (w, h) = (image.width() as f64, image.height() as f64);
    let (x, y) = (p.x.clamp(0.0, w - 1.001), p.y.clamp(0.0, h - 1.001));
    let (i, j) = (x.floor() as u32, y.floor() as u32);
    let (ax, ay) = (x - i as f64, y - j as f64);
    let g = |di: u32, dj: u32| image.get_pixel(i + di, j + dj)[0] as f64;
    (1.0 - ay) * ((1.0 - ax) * g(0, 0) + ax * g(1, 0)) + ay * ((1.0 - ax) * g(0, 1) + ax * g(1, 1))
}

/// The centre of the inner square whose top-left corner is `(i, j)`.
fn square_centre(corners: &[Point2<f64>], board: &Board, i: usize, j: usize) -> Point2<f64> {
    let c = |i, j| corners[board.index(i, j)].coords;
    Point2::from((c(i, j) + c(i + 1, j) + c(i + 1, j + 1) + c(i, j + 1)) / 4.0)
}

/// How well the inner squares' grey levels agree with the board's colours in this labelling:
/// positive when the squares the board has light are lighter.
fn colour_agreement(corners: &[Point2<f64>], board: &Board, image: &GrayImage) -> f64 {
    let [nx, ny] = board.inner();
    let mut score = 0.0;
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            let g = sample(image, square_centre(corners, board, i, j));
            score += if board.is_dark(i as i64, j as i64) { -g } else { g };
        }
    }
    score
}

/// Refuses boards seen too obliquely: the median over the inner squares of the ratio of a
/// square's shorter side to its longer.
fn check_shape(corners: &[Point2<f64>], board: &Board) -> Result<(), Dropped> {
    let [nx, ny] = board.inner();
    let mut ratios = Vec::new();
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            let c = |i, j| corners[board.index(i, j)];
            let along = ((c(i + 1, j) - c(i, j)).norm() + (c(i + 1, j + 1) - c(i, j + 1)).norm()) / 2.0;
            let down = ((c(i, j + 1) - c(i, j)).norm() + (c(i + 1, j + 1) - c(i + 1, j)).norm()) / 2.0;
            ratios.push(along.min(down) / along.max(down).max(1e-9));
        }
    }
    let ratio = median(&mut ratios);
    if ratio < MIN_FORESHORTENING { Err(Dropped::Oblique { ratio }) } else { Ok(()) }
}

/// Refuses boards whose squares are too alike or whose edges too blurred: across each inner
/// edge between two corners, the grey-level profile's step and steepest slope give the edge's
/// Gaussian spread (`step / (sqrt(2 pi) slope)`); the median over the edges.
fn check_sharpness(corners: &[Point2<f64>], board: &Board, image: &GrayImage) -> Result<(), Dropped> {
    let [nx, ny] = board.inner();
    let (mut sigmas, mut steps) = (Vec::new(), Vec::new());
    let mut edge = |a: Point2<f64>, b: Point2<f64>| {
        let along = b - a;
        let normal = Vector2::new(-along.y, along.x).normalize();
        let half = along.norm() * 0.45;
        let mid = a + along / 2.0;
        const STEP: f64 = 0.25;
        let n = (half / STEP) as i32;
        let profile: Vec<f64> = (-n..=n).map(|k| sample(image, mid + normal * (k as f64 * STEP))).collect();
        let step = (profile[profile.len() - 1] - profile[0]).abs();
        let slope = profile.windows(2).map(|w| (w[1] - w[0]).abs() / STEP).fold(0.0, f64::max);
        steps.push(step);
        if slope > 0.0 {
            sigmas.push(step / ((2.0 * std::f64::consts::PI).sqrt() * slope));
        }
    };
    for j in 0..ny {
        for i in 0..nx {
            let c = |i, j| corners[board.index(i, j)];
            if i + 1 < nx {
                edge(c(i, j), c(i + 1, j));
            }
            if j + 1 < ny {
                edge(c(i, j), c(i, j + 1));
            }
        }
    }
    let contrast = median(&mut steps);
    if contrast < MIN_CONTRAST {
        return Err(Dropped::LowContrast { contrast });
    }
    let sigma_px = median(&mut sigmas);
    if sigma_px > MAX_BLUR_SIGMA_PX { Err(Dropped::Blurred { sigma_px }) } else { Ok(()) }
}

fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}
