//! The calibration board's geometry: a checker of `squares` whose inner corners are the
//! targets, in the board's own frame (origin at the first inner corner, x along the rows of
//! corners, y down the columns, z into the board; metres). The library's board is
//! `mesh/models/board.toml`.

use nalgebra::Point3;
use serde::{Deserialize, Serialize};

/// A checkerboard target.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Board {
    /// Squares along x and y (the inner corners are one fewer each way).
    pub squares: [u32; 2],
    /// Side of a square, metres.
    pub square_m: f64,
}

impl Board {
    /// The library's board: 10 x 7 squares of 15 mm (9 x 6 inner corners).
    pub const LIBRARY: Board = Board { squares: [10, 7], square_m: 0.015 };

    /// Inner corners along x and y.
    pub fn inner(&self) -> [usize; 2] {
        [self.squares[0] as usize - 1, self.squares[1] as usize - 1]
    }

    pub fn corner_count(&self) -> usize {
        let [nx, ny] = self.inner();
        nx * ny
    }

    /// Corner `(i, j)`'s index in [`Self::points`]: row by row.
    pub fn index(&self, i: usize, j: usize) -> usize {
        j * self.inner()[0] + i
    }

    /// Every inner corner in the board's frame, row by row.
    pub fn points(&self) -> Vec<Point3<f64>> {
        let [nx, ny] = self.inner();
        (0..ny)
            .flat_map(|j| (0..nx).map(move |i| Point3::new(i as f64 * self.square_m, j as f64 * self.square_m, 0.0)))
            .collect()
    }

    /// Whether the square whose top-left corner is inner corner `(i, j)` (`-1` for the outer
    /// row or column) is dark: the square at the pattern's first corner (`(-1, -1)`) is light,
    /// as the library's board is printed.
    pub fn is_dark(&self, i: i64, j: i64) -> bool {
        (i + j).rem_euclid(2) == 1
    }
}
