//! MAVLink's local frame is NED (north, east, down); ours is `[N, E, U]` (up). The two
//! differ in the sign of the third axis only, for positions and velocities alike.

/// `[N, E, U]` -> NED.
pub fn neu_to_ned(v: [f32; 3]) -> [f32; 3] {
    [v[0], v[1], -v[2]]
}

/// NED -> `[N, E, U]`.
pub fn ned_to_neu(v: [f32; 3]) -> [f32; 3] {
    [v[0], v[1], -v[2]]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn up_is_minus_down_and_the_conversions_invert_each_other() {
        assert_eq!(neu_to_ned([1.0, 2.0, 12.0]), [1.0, 2.0, -12.0]);
        assert_eq!(ned_to_neu([1.0, 2.0, -12.0]), [1.0, 2.0, 12.0]);
        let v = [3.5, -7.25, 0.5];
        assert_eq!(ned_to_neu(neu_to_ned(v)), v);
    }
}
