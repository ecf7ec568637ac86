//! The slots of a formation: each shape's offsets around its centre, turned to its heading.
//!
//! Offsets are `[forward, right]` metres in the formation's own frame (forward along its
//! heading); a slot is `[N, E, U]` in the flight's frame. Every shape but `offsets` is
//! centred on its centroid, so `centre` is where the formation's middle is.

use aeris_schemas::{FormationPhase, MAX_VEHICLES, ShapeKind};

/// The offsets `[forward, right]` of `n` vehicles (`n <= MAX_VEHICLES`) in `shape`,
/// neighbours `spacing` metres apart (a circle's radius), centred on their centroid;
/// `explicit` are the offsets of shape `offsets`, kept as given.
pub fn formation_offsets(
    shape: ShapeKind,
    n: usize,
    spacing: f32,
    explicit: &[[f32; 2]; MAX_VEHICLES],
) -> [[f32; 2]; MAX_VEHICLES] {
    let n = n.min(MAX_VEHICLES);
    let mut out = [[0.0f32; 2]; MAX_VEHICLES];
    let middle = (n as f32 - 1.0) / 2.0;
    for (i, o) in out.iter_mut().enumerate().take(n) {
        let i_f = i as f32;
        *o = match shape {
            ShapeKind::Line => [0.0, (i_f - middle) * spacing],
            ShapeKind::Column => [(middle - i_f) * spacing, 0.0],
            ShapeKind::Wedge => {
                // the leader at the point, then one pair per rank down the two arms, 45
                // degrees behind it: neighbours on an arm `spacing` apart
                let rank = i.div_ceil(2) as f32;
                let side = if i % 2 == 1 { -1.0 } else { 1.0 };
                let arm = rank * spacing * core::f32::consts::FRAC_1_SQRT_2;
                [-arm, side * arm]
            }
            ShapeKind::Circle => {
                let a = core::f32::consts::TAU * i_f / n as f32;
                [spacing * a.cos(), spacing * a.sin()]
            }
            ShapeKind::Grid => {
                let cols = (n as f32).sqrt().ceil().max(1.0) as usize;
                [-((i / cols) as f32) * spacing, (i % cols) as f32 * spacing]
            }
            ShapeKind::Offsets => explicit[i],
        };
    }
    if shape != ShapeKind::Offsets && n > 0 {
        let mut mean = [0.0f32; 2];
        for o in &out[..n] {
            mean[0] += o[0] / n as f32;
            mean[1] += o[1] / n as f32;
        }
        for o in &mut out[..n] {
            o[0] -= mean[0];
            o[1] -= mean[1];
        }
    }
    out
}

/// The slots `[N, E, U]` of an `assume` phase for `n` vehicles: its shape's offsets
/// turned to its heading (0 = north, clockwise), around its centre, at its height. `None`
/// for a phase whose shape byte is unknown (a program that failed validation).
pub fn slots(phase: &FormationPhase, n: usize) -> Option<[[f32; 3]; MAX_VEHICLES]> {
    let shape = ShapeKind::from_u8(phase.shape)?;
    let offsets = formation_offsets(shape, n, phase.spacing_m, &phase.offsets);
    let (sin, cos) = phase.heading_rad.sin_cos();
    let mut out = [[0.0f32; 3]; MAX_VEHICLES];
    for (slot, [f, r]) in out.iter_mut().zip(offsets).take(n.min(MAX_VEHICLES)) {
        *slot = [
            phase.centre[0] + f * cos - r * sin,
            phase.centre[1] + f * sin + r * cos,
            phase.height_m,
        ];
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use aeris_schemas::PhaseKind;

    fn assume(shape: ShapeKind, spacing: f32, heading: f32) -> FormationPhase {
        FormationPhase {
            kind: PhaseKind::Assume as u8,
            shape: shape as u8,
            height_m: 5.0,
            spacing_m: spacing,
            heading_rad: heading,
            centre: [10.0, -4.0],
            ..FormationPhase::default()
        }
    }

    fn dist(a: [f32; 3], b: [f32; 3]) -> f32 {
        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
    }

    fn close(a: f32, b: f32) -> bool {
        (a - b).abs() < 1e-4
    }

    #[test]
    fn a_line_heading_north_lies_west_to_east_around_its_centre() {
        let s = slots(&assume(ShapeKind::Line, 3.0, 0.0), 4).unwrap();
        let east: Vec<f32> = s[..4].iter().map(|p| p[1]).collect();
        assert!(
            east.iter()
                .zip([-8.5, -5.5, -2.5, 0.5])
                .all(|(a, b)| close(*a, b)),
            "{east:?}"
        );
        assert!(s[..4].iter().all(|p| close(p[0], 10.0) && p[2] == 5.0));
    }

    #[test]
    fn the_heading_turns_the_shape_clockwise() {
        // a column heading east: the vehicles one behind the other from east to west
        let s = slots(
            &assume(ShapeKind::Column, 2.0, core::f32::consts::FRAC_PI_2),
            3,
        )
        .unwrap();
        assert!(close(s[0][1], -2.0) && close(s[1][1], -4.0) && close(s[2][1], -6.0));
        assert!(s[..3].iter().all(|p| close(p[0], 10.0)));
        // a V heading north: its leader ahead (north) of the others
        let v = slots(&assume(ShapeKind::Wedge, 3.0, 0.0), 5).unwrap();
        assert!(v[1..5].iter().all(|p| p[0] < v[0][0]));
        assert!(v[1][1] < v[0][1] && v[2][1] > v[0][1], "two arms");
    }

    #[test]
    fn neighbours_are_spacing_apart_in_every_shape() {
        for (shape, n, spacing, nearest) in [
            (ShapeKind::Line, 4, 3.0, 3.0),
            (ShapeKind::Column, 5, 2.5, 2.5),
            (ShapeKind::Wedge, 5, 3.0, 3.0),
            (ShapeKind::Grid, 6, 4.0, 4.0),
            // 4 on a circle of radius 6 m: a square's side, 6 * sqrt(2)
            (ShapeKind::Circle, 4, 6.0, 6.0 * core::f32::consts::SQRT_2),
        ] {
            let s = slots(&assume(shape, spacing, 0.7), n).unwrap();
            let mut min = f32::INFINITY;
            for i in 0..n {
                for j in i + 1..n {
                    min = min.min(dist(s[i], s[j]));
                }
            }
            assert!(close(min, nearest), "{shape:?}: nearest pair {min} m");
        }
    }

    #[test]
    fn explicit_offsets_are_kept_and_turned() {
        let mut p = assume(ShapeKind::Offsets, 0.0, core::f32::consts::PI);
        p.offsets[0] = [2.0, 0.0];
        p.offsets[1] = [0.0, 3.0];
        let s = slots(&p, 2).unwrap();
        // heading south: forward is south, right is west
        assert!(close(s[0][0], 8.0) && close(s[0][1], -4.0));
        assert!(close(s[1][0], 10.0) && close(s[1][1], -7.0));
        assert!(slots(&FormationPhase { shape: 0, ..p }, 2).is_none());
    }
}
