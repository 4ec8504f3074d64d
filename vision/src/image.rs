//! Grey images as the pipeline sees them: row-major, `y` down, pixel centres at integer
//! coordinates; and the nearest pixel to a point, and the integer at or below a value.

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
    // Every value from 2^52 up is whole (and the infinities and NaN go as the cast takes them):
    // below, the cast cannot saturate, nor the step overflow.
    if x.abs() >= WHOLE_FROM {
        return x as i64;
    }
    let towards_zero = x as i64;
    let fraction = x - towards_zero as f64;
    // Without branches: which way a sample's fraction falls is a coin toss, and a mispredicted
    // branch costs more than the comparisons.
    towards_zero + i64::from(fraction >= 0.5) - i64::from(fraction <= -0.5)
}

/// 2^52: from here up every `f64` is a whole number.
const WHOLE_FROM: f64 = 4_503_599_627_370_496.0;

/// `x.floor() as i64`, without the call to the C library's `floor` (see [`nearest_px`]): the
/// matcher takes the floor of a place for every hypothesis it records and of two angles for
/// every edge it checks in the image. Exact for every `x`, saturating as the cast does.
pub fn floor_int(x: f64) -> i64 {
    let towards_zero = x as i64;
    // Below zero the cast rounded up, unless `x` was whole.
    towards_zero.saturating_sub(i64::from(towards_zero as f64 > x))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The nearest pixel is `round`'s, halves (away from zero), negatives, the values either
    /// side of a half, either side of 2^52, the far ends, the infinities and NaN included.
    #[test]
    fn the_nearest_pixel_is_the_one_round_gives() {
        let mut values = vec![0.0, -0.0, 0.5, -0.5, 1.5, -1.5, 2.5, 511.5, -2.5, 1e15 + 0.5, f64::MAX, f64::MIN];
        let whole_from = 2f64.powi(52);
        values.extend([whole_from, -whole_from, whole_from.next_down(), -whole_from.next_down(), 9.3e18, -9.3e18]);
        values.extend([f64::INFINITY, f64::NEG_INFINITY, f64::NAN]);
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

    /// The integer at or below a value is `floor`'s, whole values, negatives, values either
    /// side of whole ones, the infinities, NaN and the far ends included.
    #[test]
    fn the_integer_below_is_the_one_floor_gives() {
        let mut values =
            vec![0.0, -0.0, 0.5, -0.5, 1.0, -1.0, 1e15 + 0.5, -1e15 - 0.5, 9.3e18, -9.3e18, f64::MAX, f64::MIN];
        values.extend([f64::INFINITY, f64::NEG_INFINITY, f64::NAN, f64::MIN_POSITIVE, -f64::MIN_POSITIVE]);
        for k in -2000..2000 {
            let x = k as f64 * 0.25;
            values.extend([x, x.next_up(), x.next_down()]);
        }
        for x in values {
            assert_eq!(floor_int(x), x.floor() as i64, "{x:e}");
        }
    }
}
