//! Edge strings: edgels linked into ordered chains of 8-connected pixels. A string starts at an
//! end (an edgel with a single neighbour) where there is one, follows the nearest unused
//! neighbour (4-connected before diagonal, then the one straightest ahead), and stops where no
//! unused neighbour is left; closed contours become strings that start anywhere on them.

use super::canny::{EdgeMap, neighbours};

/// An ordered chain of edgels (indices into [`EdgeMap::edgels`]).
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct EdgeString {
    pub edgels: Vec<u32>,
}

/// Strings shorter than this many edgels are dropped (by the front end's callers of
/// [`link_strings`]).
pub const MIN_STRING: usize = 5;

/// Links the edgels of `map` into strings, dropping those of fewer than `min_len` edgels.
pub fn link_strings(map: &EdgeMap, min_len: usize) -> Vec<EdgeString> {
    let n = map.edgels.len();
    let neighbours_of = |i: u32| {
        let (x, y) = map.pixel_of(i);
        neighbours(x, y, map.width, map.height).filter_map(move |(nx, ny)| map.edgel_at(nx, ny))
    };
    let mut used = vec![false; n];
    let ends = (0..n as u32).filter(|&i| neighbours_of(i).count() == 1);
    let starts: Vec<u32> = ends.chain(0..n as u32).collect();
    let mut strings = Vec::new();
    for start in starts {
        if used[start as usize] {
            continue;
        }
        let mut chain = walk(map, start, &mut used);
        // Started mid-contour: extend the other way too.
        let back = walk_from(map, start, &mut used, None);
        if back.len() > 1 {
            let mut joined: Vec<u32> = back[1..].iter().rev().copied().collect();
            joined.append(&mut chain);
            chain = joined;
        }
        if chain.len() >= min_len {
            strings.push(EdgeString { edgels: chain });
        }
    }
    strings
}

fn walk(map: &EdgeMap, start: u32, used: &mut [bool]) -> Vec<u32> {
    walk_from(map, start, used, None)
}

/// Follows unused neighbours from `start` (marking them used); `heading` is the last step.
fn walk_from(map: &EdgeMap, start: u32, used: &mut [bool], mut heading: Option<(i32, i32)>) -> Vec<u32> {
    let mut chain = vec![start];
    used[start as usize] = true;
    let mut at = start;
    loop {
        let (x, y) = map.pixel_of(at);
        let next = neighbours(x, y, map.width, map.height)
            .filter_map(|(nx, ny)| Some((map.edgel_at(nx, ny)?, (nx as i32 - x as i32, ny as i32 - y as i32))))
            .filter(|&(j, _)| !used[j as usize])
            .min_by_key(|&(_, (dx, dy))| {
                let diagonal = i32::from(dx != 0 && dy != 0);
                let turn = heading.map_or(0, |(hx, hy)| 2 - (hx * dx + hy * dy)); // 0 straight .. 4 back
                (diagonal, turn)
            });
        let Some((j, step)) = next else { return chain };
        used[j as usize] = true;
        chain.push(j);
        heading = Some(step);
        at = j;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::front_end::canny::{CannyParams, canny};
    use crate::image::GreyImage;

    fn square_image() -> GreyImage {
        let (w, h) = (64, 64);
        let pixels = (0..w * h)
            .map(|i| if (20..44).contains(&(i % w)) && (16..40).contains(&(i / w)) { 200 } else { 50 })
            .collect();
        GreyImage::new(w, h, pixels).unwrap()
    }

    #[test]
    fn a_square_outline_is_one_closed_string() {
        let map = canny(&square_image(), &CannyParams::default());
        let strings = link_strings(&map, 5);
        assert_eq!(strings.len(), 1, "strings: {:?}", strings.iter().map(|s| s.edgels.len()).collect::<Vec<_>>());
        let s = &strings[0];
        assert!(s.edgels.len() >= 4 * 20, "only {} edgels around a 24 px square", s.edgels.len());
        // Consecutive edgels are 8-neighbours.
        for w in s.edgels.windows(2) {
            let ((x0, y0), (x1, y1)) = (map.pixel_of(w[0]), map.pixel_of(w[1]));
            assert!(x0.abs_diff(x1) <= 1 && y0.abs_diff(y1) <= 1);
        }
        // And the string closes on itself.
        let ((xa, ya), (xb, yb)) = (map.pixel_of(s.edgels[0]), map.pixel_of(*s.edgels.last().unwrap()));
        assert!(xa.abs_diff(xb) <= 1 && ya.abs_diff(yb) <= 1);
    }

    #[test]
    fn short_strings_are_dropped() {
        let map = canny(&square_image(), &CannyParams::default());
        assert!(link_strings(&map, 10_000).is_empty());
    }
}
