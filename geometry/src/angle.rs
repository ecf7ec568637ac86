//! Angles.

use core::f32::consts::{PI, TAU};

/// `a` (rad) as the same angle in `[-pi, pi]`; a half turn maps to `-pi`.
///
/// A non-finite `a` gives NaN: it has no wrapped equivalent, and NaN keeps the fault
/// visible to the checks downstream (setpoint and decision validation, the multirotor's
/// finite-command check, the controller's output guard) where a made-up angle such as 0
/// (north) would pass them and be flown.
pub fn wrap_pi(a: f32) -> f32 {
    // an angle already in [-pi, pi) is returned as it is: wrapping it through `rem_euclid`
    // would round it (1.25 came back as 1.2500002), so a yaw that only passes through a
    // wrap (an interpolation between two equal samples) would not be the yaw sent
    if (-PI..PI).contains(&a) {
        return a;
    }
    // rem_euclid is in [0, TAU] after rounding: the result is in [-pi, pi] except for NaN
    ((a + PI).rem_euclid(TAU) - PI).clamp(-PI, PI)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_angle_in_range_comes_back_unchanged() {
        for a in [0.0, 1.25, -1.25, 3.0, -3.0, -PI, 1e-7] {
            assert_eq!(wrap_pi(a).to_bits(), a.to_bits(), "{a}");
        }
    }

    #[test]
    fn wraps_into_minus_pi_to_pi() {
        assert!((wrap_pi(3.0 * PI) - PI).abs() < 1e-5 || (wrap_pi(3.0 * PI) + PI).abs() < 1e-5);
        assert!((wrap_pi(0.5 + 2.0 * PI) - 0.5).abs() < 1e-5);
        assert!((wrap_pi(-0.5 - 4.0 * PI) + 0.5).abs() < 1e-5);
        assert!((wrap_pi(7.0) - (7.0 - TAU)).abs() < 1e-5);
        assert!((wrap_pi(-4.0) - (-4.0 + TAU)).abs() < 1e-5);
        assert_eq!(wrap_pi(0.25), 0.25);
        // a half turn is -pi (the VLN generator's turn directions rely on it)
        assert_eq!(wrap_pi(PI), -PI);
        assert_eq!(wrap_pi(-PI), -PI);
    }

    #[test]
    fn stays_in_range_for_large_and_tiny_angles() {
        for a in [
            1e6f32, -1e6, 3.0e38, -3.0e38, 1e-30, -1e-30, -1e-8, TAU, -TAU,
        ] {
            let w = wrap_pi(a);
            assert!((-PI..=PI).contains(&w), "{a} -> {w}");
        }
    }

    #[test]
    fn a_non_finite_angle_stays_non_finite() {
        for a in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            assert!(wrap_pi(a).is_nan(), "{a} -> {}", wrap_pi(a));
        }
    }
}
