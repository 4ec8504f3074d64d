//! Parsers and limits for the command line's numbers, so that a value out of range is refused
//! by name before any work starts.

/// Most scenes (or trials, or runs) one evaluation or benchmark takes.
pub const MAX_COUNT: u64 = 100_000;
/// Largest first seed of an evaluation: seed + k never wraps for any count allowed.
pub const MAX_FIRST_SEED: u64 = u64::MAX / 2;

/// A duration in seconds: finite, positive, at most a day.
pub fn seconds(s: &str) -> Result<f64, String> {
    let v: f64 = s.trim().parse().map_err(|e| format!("`{s}` is not a number: {e}"))?;
    if v.is_finite() && v > 0.0 && v <= 86_400.0 {
        Ok(v)
    } else {
        Err(format!("{v} is not a duration: seconds must be within (0, 86400]"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_must_be_finite_and_positive() {
        assert_eq!(seconds("2.5"), Ok(2.5));
        for bad in ["0", "-1", "nan", "inf", "1e9", "soon"] {
            assert!(seconds(bad).is_err(), "{bad}");
        }
    }
}
