//! Grey images as the pipeline sees them: row-major, `y` down, pixel centres at integer
//! coordinates.

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
