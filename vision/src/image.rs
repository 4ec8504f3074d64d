//! Grey images as the pipeline sees them: row-major, `y` down, pixel centres at integer
//! coordinates; and the nearest pixel to a point.

/// An 8-bit grey image.
#[derive(Debug, Clone, PartialEq)]
pub struct GreyImage {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<u8>,
}

impl GreyImage {
    /// Wraps row-major pixels; `None` when their count is not `width * height`.
    pub fn new(width: usize, height: usize, pixels: Vec<u8>) -> Option<GreyImage> {
        (pixels.len() == width * height).then_some(GreyImage { width, height, pixels })
    }

    pub fn at(&self, x: usize, y: usize) -> u8 {
        self.pixels[y * self.width + x]
    }
}

/// `x.round() as i64`, without the call to the C library's `round` that the baseline x86-64
/// instruction set needs for it (it has no rounding instruction): the matcher's image checks
/// take the nearest pixel of every sample, and those calls were a tenth of its time. Rounds
/// half away from zero as `round` does; `x - trunc(x)` is exact below 2^52.
pub fn nearest_px(x: f64) -> i64 {
    let towards_zero = x as i64;
    let fraction = x - towards_zero as f64;
    // Without branches: which way a sample's fraction falls is a coin toss, and a mispredicted
    // branch costs more than the comparisons.
    let step = i64::from(fraction >= 0.5) - i64::from(fraction <= -0.5);
    towards_zero.saturating_add(step)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The nearest pixel is `round`'s, halves (away from zero), negatives, the values either
    /// side of a half and the far ends included.
    #[test]
    fn the_nearest_pixel_is_the_one_round_gives() {
        let mut values = vec![0.0, -0.0, 0.5, -0.5, 1.5, -1.5, 2.5, 511.5, -2.5, 1e15 + 0.5, f64::MAX, f64::MIN];
        for k in -2000..2000 {
            let x = k as f64 * 0.25;
            values.extend([x, x.next_up(), x.next_down()]);
        }
        let mut state = 3u64;
        values.extend((0..10_000).map(|_| {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.3) * 700.0
        }));
        for x in values {
            assert_eq!(nearest_px(x), x.round() as i64, "{x:e}");
        }
    }
}
