//! The formation program: what a swarm of N vehicles is to fly, phase by phase (the
//! paper's multi-UAV formation experiment). A formation reasoning role produces it from an
//! instruction; nothing flies before [`FormationProgram::validate`] passed.
//!
//! Fixed-size like every message here: at most [`MAX_PHASES`] phases for at most
//! [`MAX_VEHICLES`] vehicles. Positions are `[N, E, U]` metres of the flight's local frame;
//! headings are radians, 0 = north, positive clockwise (to east), as D_t's yaw.

use crate::all_finite;
use iceoryx2_bb_derive_macros::ZeroCopySend;
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;

/// Most phases in one program.
pub const MAX_PHASES: usize = 16;
/// Most vehicles one program flies.
pub const MAX_VEHICLES: usize = 8;

/// What a phase does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum PhaseKind {
    /// Every vehicle climbs, where it stands, to `height_m`.
    TakeOff = 1,
    /// The vehicles assume `shape` around `centre` at `height_m` (`spacing_m` apart; a
    /// circle's radius), facing `heading_rad`.
    Assume = 2,
    /// Hold the current formation for `hold_s`.
    Hold = 3,
    /// Move the whole formation, shape kept, until its centre is at `centre`, at
    /// `speed_mps`.
    Move = 4,
    /// Every vehicle lands where it is.
    Land = 5,
}

impl PhaseKind {
    /// The kind whose wire byte is `b`.
    pub fn from_u8(b: u8) -> Option<Self> {
        Some(match b {
            1 => Self::TakeOff,
            2 => Self::Assume,
            3 => Self::Hold,
            4 => Self::Move,
            5 => Self::Land,
            _ => return None,
        })
    }

    /// Its name in programs and messages (`take_off`, `assume`, `hold`, `move`, `land`).
    pub fn name(self) -> &'static str {
        match self {
            Self::TakeOff => "take_off",
            Self::Assume => "assume",
            Self::Hold => "hold",
            Self::Move => "move",
            Self::Land => "land",
        }
    }
}

/// The geometry of a formation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum ShapeKind {
    /// Abreast, across the heading.
    Line = 1,
    /// One behind the other, along the heading.
    Column = 2,
    /// A V whose point leads along the heading.
    Wedge = 3,
    /// Evenly around a circle of radius `spacing_m`.
    Circle = 4,
    /// Rows of `ceil(sqrt(N))`, `spacing_m` apart both ways.
    Grid = 5,
    /// Each vehicle at its own offset from the centre (`offsets`, before the heading's
    /// rotation).
    Offsets = 6,
}

impl ShapeKind {
    /// The shape whose wire byte is `b`.
    pub fn from_u8(b: u8) -> Option<Self> {
        Some(match b {
            1 => Self::Line,
            2 => Self::Column,
            3 => Self::Wedge,
            4 => Self::Circle,
            5 => Self::Grid,
            6 => Self::Offsets,
            _ => return None,
        })
    }

    /// Its name in programs and messages.
    pub fn name(self) -> &'static str {
        match self {
            Self::Line => "line",
            Self::Column => "column",
            Self::Wedge => "wedge",
            Self::Circle => "circle",
            Self::Grid => "grid",
            Self::Offsets => "offsets",
        }
    }
}

/// One phase of a [`FormationProgram`]. Fields a kind does not use stay 0.
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[type_name("aeris::FormationPhase@s8")]
#[repr(C)]
pub struct FormationPhase {
    /// [`PhaseKind`] wire byte.
    pub kind: u8,
    /// [`ShapeKind`] wire byte (`assume` only).
    pub shape: u8,
    /// Padding (0).
    pub reserved: [u8; 2],
    /// Height above the ground (m): `take_off`'s and `assume`'s.
    pub height_m: f32,
    /// Distance between neighbours (m), or a circle's radius (`assume`).
    pub spacing_m: f32,
    /// The formation's heading (rad, [-pi, pi]; `assume`).
    pub heading_rad: f32,
    /// How long to hold (s; `hold`).
    pub hold_s: f32,
    /// Speed of the formation's centre (m/s; `move`).
    pub speed_mps: f32,
    /// The formation's centre `[N, E]` (m): `assume`'s and `move`'s destination.
    pub centre: [f32; 2],
    /// Each vehicle's offset `[forward, right]` from the centre (m; shape `offsets`, the
    /// first `vehicles` entries).
    pub offsets: [[f32; 2]; MAX_VEHICLES],
}

/// A formation program: its phases, in order, for `vehicles`
/// vehicles.
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[type_name("aeris::FormationProgram@s8")]
#[repr(C)]
pub struct FormationProgram {
    /// Publisher sequence number.
    pub seq: u64,
    /// Vehicles it flies (1..=[`MAX_VEHICLES`]).
    pub vehicles: u8,
    /// Phases in use (1..=[`MAX_PHASES`]).
    pub phase_count: u8,
    /// Padding (0).
    pub reserved: [u8; 6],
    /// The phases; the first `phase_count` are the program.
    pub phases: [FormationPhase; MAX_PHASES],
}

/// The bounds a formation program must keep (the flight's, from its workflow).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FormationLimits {
    /// Vehicles the flight has.
    pub vehicles: u8,
    /// Lowest height of a take-off or formation (m).
    pub h_min: f32,
    /// Highest (m).
    pub h_max: f32,
    /// Smallest distance between neighbours or circle radius (m): two vehicles never
    /// closer than this.
    pub min_separation_m: f32,
    /// Largest distance between neighbours, circle radius or offset (m).
    pub max_spacing_m: f32,
    /// Fastest a formation moves (m/s).
    pub v_max: f32,
    /// Longest hold (s).
    pub max_hold_s: f32,
    /// Geofence lower corner `[N, E]` (m): every centre inside.
    pub geofence_min: [f32; 2],
    /// Geofence upper corner `[N, E]` (m).
    pub geofence_max: [f32; 2],
}

impl Default for FormationLimits {
    /// Four vehicles, 2-60 m, 2 m minimum and 30 m maximum spacing, 8 m/s, holds up to 120 s,
    /// a 400 m square geofence: the defaults of [`crate::DecisionLimits`] where they
    /// overlap.
    fn default() -> Self {
        Self {
            vehicles: 4,
            h_min: 2.0,
            h_max: 60.0,
            min_separation_m: 2.0,
            max_spacing_m: 30.0,
            v_max: 8.0,
            max_hold_s: 120.0,
            geofence_min: [-200.0, -200.0],
            geofence_max: [200.0, 200.0],
        }
    }
}

impl FormationLimits {
    /// `true` when the limits themselves are coherent (finite, ordered, non-empty).
    pub fn is_coherent(&self) -> bool {
        all_finite(&[
            self.h_min,
            self.h_max,
            self.min_separation_m,
            self.max_spacing_m,
            self.v_max,
            self.max_hold_s,
        ]) && all_finite(&self.geofence_min)
            && all_finite(&self.geofence_max)
            && (1..=MAX_VEHICLES as u8).contains(&self.vehicles)
            && 0.0 <= self.h_min
            && self.h_min <= self.h_max
            && 0.0 < self.min_separation_m
            && self.min_separation_m <= self.max_spacing_m
            && self.v_max > 0.0
            && self.max_hold_s > 0.0
            && (0..2).all(|i| self.geofence_min[i] <= self.geofence_max[i])
    }
}

/// Why a formation program is invalid. Phases are numbered from 1, as a user counts them.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum FormationError {
    /// The limits checked against are themselves incoherent.
    #[error("the formation limits are incoherent")]
    IncoherentLimits,
    /// No vehicle, more than [`MAX_VEHICLES`], or more than the flight has.
    #[error("{vehicles} vehicles: the flight has {available} (at most {MAX_VEHICLES})")]
    Vehicles {
        /// Vehicles the program names.
        vehicles: u8,
        /// Vehicles the flight has.
        available: u8,
    },
    /// No phase, or more than [`MAX_PHASES`].
    #[error("{0} phases: a program has 1 to {MAX_PHASES}")]
    PhaseCount(u8),
    /// A phase kind byte that is no [`PhaseKind`].
    #[error("phase {phase}: unknown kind {kind}")]
    UnknownKind {
        /// The phase (1-based).
        phase: usize,
        /// Its kind byte.
        kind: u8,
    },
    /// A shape byte that is no [`ShapeKind`] in an `assume` phase.
    #[error("phase {phase}: unknown shape {shape}")]
    UnknownShape {
        /// The phase (1-based).
        phase: usize,
        /// Its shape byte.
        shape: u8,
    },
    /// A number that is NaN or infinite.
    #[error("phase {phase}: {field} is not a finite number")]
    NonFinite {
        /// The phase (1-based).
        phase: usize,
        /// The field.
        field: &'static str,
    },
    /// A number outside its bounds.
    #[error("phase {phase}: {field} = {value} is outside [{min}, {max}]")]
    OutOfRange {
        /// The phase (1-based).
        phase: usize,
        /// The field.
        field: &'static str,
        /// Its value.
        value: f32,
        /// Lowest allowed.
        min: f32,
        /// Highest allowed.
        max: f32,
    },
    /// The program does not start with `take_off`.
    #[error("phase 1 is `{0}`: a program starts with take_off")]
    FirstNotTakeOff(&'static str),
    /// A `take_off` after the first phase, or a phase after `land`.
    #[error("phase {phase}: `{kind}` cannot follow {after}")]
    Order {
        /// The phase (1-based).
        phase: usize,
        /// Its kind.
        kind: &'static str,
        /// What it may not follow.
        after: &'static str,
    },
    /// A `hold` or `move` before any `assume`: there is no formation to keep.
    #[error("phase {phase}: `{kind}` before any assume: there is no formation yet")]
    NoFormation {
        /// The phase (1-based).
        phase: usize,
        /// Its kind.
        kind: &'static str,
    },
    /// The program does not end with `land`.
    #[error("the last phase is `{0}`: a program ends with land")]
    LastNotLand(&'static str),
}

impl FormationProgram {
    /// The phases in use (at most [`MAX_PHASES`], whatever `phase_count` says).
    pub fn phases(&self) -> &[FormationPhase] {
        &self.phases[..(self.phase_count as usize).min(MAX_PHASES)]
    }

    /// Valid(program): presence, order, types and ranges, deterministically, against
    /// `limits`. NaN and inf are invalid. Range checks only: whether the vehicles keep
    /// their separation between shapes is the simulation's to find.
    pub fn validate(&self, limits: &FormationLimits) -> Result<(), FormationError> {
        if !limits.is_coherent() {
            return Err(FormationError::IncoherentLimits);
        }
        if self.vehicles == 0 || self.vehicles > limits.vehicles {
            return Err(FormationError::Vehicles {
                vehicles: self.vehicles,
                available: limits.vehicles,
            });
        }
        let count = self.phase_count as usize;
        if count == 0 || count > MAX_PHASES {
            return Err(FormationError::PhaseCount(self.phase_count));
        }
        let mut formed = false;
        let mut landed = false;
        for (i, p) in self.phases().iter().enumerate() {
            let phase = i + 1;
            let kind = PhaseKind::from_u8(p.kind).ok_or(FormationError::UnknownKind {
                phase,
                kind: p.kind,
            })?;
            if landed {
                return Err(FormationError::Order {
                    phase,
                    kind: kind.name(),
                    after: "land",
                });
            }
            match (i, kind) {
                (0, PhaseKind::TakeOff) => {}
                (0, other) => return Err(FormationError::FirstNotTakeOff(other.name())),
                (_, PhaseKind::TakeOff) => {
                    return Err(FormationError::Order {
                        phase,
                        kind: kind.name(),
                        after: "the first phase",
                    });
                }
                _ => {}
            }
            p.validate(phase, kind, self.vehicles, limits)?;
            match kind {
                PhaseKind::Assume => formed = true,
                PhaseKind::Hold | PhaseKind::Move if !formed => {
                    return Err(FormationError::NoFormation {
                        phase,
                        kind: kind.name(),
                    });
                }
                PhaseKind::Land => landed = true,
                _ => {}
            }
        }
        if !landed {
            let last = PhaseKind::from_u8(self.phases()[count - 1].kind).map_or("?", |k| k.name());
            return Err(FormationError::LastNotLand(last));
        }
        Ok(())
    }
}

impl FormationPhase {
    /// The checks of one phase of kind `kind` (number `phase`) for `vehicles` vehicles.
    fn validate(
        &self,
        phase: usize,
        kind: PhaseKind,
        vehicles: u8,
        limits: &FormationLimits,
    ) -> Result<(), FormationError> {
        let offsets = &self.offsets[..vehicles as usize];
        let mut numbers = [
            ("height", self.height_m),
            ("spacing", self.spacing_m),
            ("heading", self.heading_rad),
            ("hold", self.hold_s),
            ("speed", self.speed_mps),
            ("centre.n", self.centre[0]),
            ("centre.e", self.centre[1]),
        ]
        .into_iter()
        .chain(
            offsets
                .iter()
                .flat_map(|o| [("offset", o[0]), ("offset", o[1])]),
        );
        if let Some((field, _)) = numbers.find(|(_, v)| !v.is_finite()) {
            return Err(FormationError::NonFinite { phase, field });
        }
        let range = |field: &'static str, value: f32, min: f32, max: f32| {
            if (min..=max).contains(&value) {
                Ok(())
            } else {
                Err(FormationError::OutOfRange {
                    phase,
                    field,
                    value,
                    min,
                    max,
                })
            }
        };
        let pi = core::f32::consts::PI;
        let centre = |c: [f32; 2]| {
            range(
                "centre.n",
                c[0],
                limits.geofence_min[0],
                limits.geofence_max[0],
            )?;
            range(
                "centre.e",
                c[1],
                limits.geofence_min[1],
                limits.geofence_max[1],
            )
        };
        match kind {
            PhaseKind::TakeOff => range("height", self.height_m, limits.h_min, limits.h_max),
            PhaseKind::Assume => {
                let shape = ShapeKind::from_u8(self.shape).ok_or(FormationError::UnknownShape {
                    phase,
                    shape: self.shape,
                })?;
                range("height", self.height_m, limits.h_min, limits.h_max)?;
                range("heading", self.heading_rad, -pi, pi)?;
                centre(self.centre)?;
                if shape == ShapeKind::Offsets {
                    let reach = limits.max_spacing_m * f32::from(vehicles);
                    for o in offsets {
                        range("offset", o[0].hypot(o[1]), 0.0, reach)?;
                    }
                    Ok(())
                } else {
                    range(
                        "spacing",
                        self.spacing_m,
                        limits.min_separation_m,
                        limits.max_spacing_m,
                    )
                }
            }
            PhaseKind::Hold => range("hold", self.hold_s, 0.1, limits.max_hold_s),
            PhaseKind::Move => {
                range("speed", self.speed_mps, 0.1, limits.v_max)?;
                centre(self.centre)
            }
            PhaseKind::Land => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn phase(kind: PhaseKind) -> FormationPhase {
        FormationPhase {
            kind: kind as u8,
            ..FormationPhase::default()
        }
    }

    /// take off to 5 m, a line 3 m apart, hold 10 s, move north at 2 m/s, a circle of
    /// 6 m, land: valid for four vehicles.
    fn program() -> FormationProgram {
        let mut p = FormationProgram {
            vehicles: 4,
            ..FormationProgram::default()
        };
        let phases = [
            FormationPhase {
                height_m: 5.0,
                ..phase(PhaseKind::TakeOff)
            },
            FormationPhase {
                shape: ShapeKind::Line as u8,
                height_m: 5.0,
                spacing_m: 3.0,
                ..phase(PhaseKind::Assume)
            },
            FormationPhase {
                hold_s: 10.0,
                ..phase(PhaseKind::Hold)
            },
            FormationPhase {
                speed_mps: 2.0,
                centre: [20.0, 0.0],
                ..phase(PhaseKind::Move)
            },
            FormationPhase {
                shape: ShapeKind::Circle as u8,
                height_m: 5.0,
                spacing_m: 6.0,
                centre: [20.0, 0.0],
                ..phase(PhaseKind::Assume)
            },
            phase(PhaseKind::Land),
        ];
        p.phases[..phases.len()].copy_from_slice(&phases);
        p.phase_count = phases.len() as u8;
        p
    }

    #[test]
    fn a_well_formed_program_is_valid() {
        assert_eq!(program().validate(&FormationLimits::default()), Ok(()));
    }

    #[test]
    fn every_field_is_bounded() {
        let limits = FormationLimits::default();
        type Edit = fn(&mut FormationProgram);
        let cases: [(Edit, &str); 14] = [
            (|p| p.phases[0].height_m = 1.0, "phase 1: height = 1"),
            (|p| p.phases[0].height_m = 61.0, "phase 1: height = 61"),
            (|p| p.phases[1].spacing_m = 1.5, "phase 2: spacing = 1.5"),
            (|p| p.phases[1].spacing_m = 31.0, "phase 2: spacing = 31"),
            (|p| p.phases[1].heading_rad = 3.3, "phase 2: heading = 3.3"),
            (|p| p.phases[1].centre[0] = 250.0, "phase 2: centre.n = 250"),
            (
                |p| p.phases[1].height_m = f32::NAN,
                "phase 2: height is not",
            ),
            (|p| p.phases[1].shape = 9, "phase 2: unknown shape 9"),
            (|p| p.phases[2].hold_s = 0.0, "phase 3: hold = 0"),
            (|p| p.phases[2].hold_s = 121.0, "phase 3: hold = 121"),
            (|p| p.phases[3].speed_mps = 9.0, "phase 4: speed = 9"),
            (
                |p| p.phases[3].centre[1] = -201.0,
                "phase 4: centre.e = -201",
            ),
            (
                |p| p.phases[3].speed_mps = f32::INFINITY,
                "phase 4: speed is not",
            ),
            (|p| p.phases[4].kind = 0, "phase 5: unknown kind 0"),
        ];
        for (edit, needle) in cases {
            let mut p = program();
            edit(&mut p);
            let e = p.validate(&limits).expect_err(needle).to_string();
            assert!(e.starts_with(needle), "{e:?} is not {needle:?}");
        }
    }

    #[test]
    fn explicit_offsets_are_bounded_and_finite() {
        let limits = FormationLimits::default();
        let mut p = program();
        p.phases[1].shape = ShapeKind::Offsets as u8;
        p.phases[1].spacing_m = 0.0;
        p.phases[1].offsets[..4].copy_from_slice(&[[0.0, 0.0], [3.0, 0.0], [0.0, 3.0], [3.0, 3.0]]);
        assert_eq!(p.validate(&limits), Ok(()));
        p.phases[1].offsets[3] = [200.0, 0.0];
        assert!(matches!(
            p.validate(&limits),
            Err(FormationError::OutOfRange {
                field: "offset",
                ..
            })
        ));
        p.phases[1].offsets[3] = [f32::NAN, 0.0];
        assert!(matches!(
            p.validate(&limits),
            Err(FormationError::NonFinite {
                field: "offset",
                ..
            })
        ));
        // offsets past the program's vehicles are not its
        p.phases[1].offsets[3] = [0.0, 0.0];
        p.phases[1].offsets[5] = [f32::NAN, 1e9];
        assert_eq!(p.validate(&limits), Ok(()));
    }

    #[test]
    fn empty_too_long_or_out_of_order_programs_are_invalid() {
        let limits = FormationLimits::default();
        let mut p = program();
        p.phase_count = 0;
        assert_eq!(p.validate(&limits), Err(FormationError::PhaseCount(0)));
        p.phase_count = MAX_PHASES as u8 + 1;
        assert_eq!(p.validate(&limits), Err(FormationError::PhaseCount(17)));
        // too many vehicles for the flight, and none
        let mut p = program();
        p.vehicles = 5;
        assert!(matches!(
            p.validate(&limits),
            Err(FormationError::Vehicles {
                vehicles: 5,
                available: 4
            })
        ));
        p.vehicles = 0;
        assert!(p.validate(&limits).is_err());
        // no take-off first; a second take-off; a hold before any shape
        let mut p = program();
        p.phases.swap(0, 1);
        assert_eq!(
            p.validate(&limits),
            Err(FormationError::FirstNotTakeOff("assume"))
        );
        let mut p = program();
        p.phases[2] = p.phases[0];
        assert!(matches!(
            p.validate(&limits),
            Err(FormationError::Order {
                phase: 3,
                kind: "take_off",
                ..
            })
        ));
        let mut p = program();
        p.phases[1] = p.phases[2];
        assert_eq!(
            p.validate(&limits),
            Err(FormationError::NoFormation {
                phase: 2,
                kind: "hold"
            })
        );
        // nothing after land, and land last
        let mut p = program();
        p.phases[3] = phase(PhaseKind::Land);
        assert!(matches!(
            p.validate(&limits),
            Err(FormationError::Order {
                phase: 5,
                after: "land",
                ..
            })
        ));
        let mut p = program();
        p.phase_count = 5;
        assert_eq!(
            p.validate(&limits),
            Err(FormationError::LastNotLand("assume"))
        );
        // a full program of 16 phases is fine
        let mut p = program();
        let hold = p.phases[2];
        for i in 5..MAX_PHASES - 1 {
            p.phases[i] = hold;
        }
        p.phases[MAX_PHASES - 1] = phase(PhaseKind::Land);
        p.phase_count = MAX_PHASES as u8;
        assert_eq!(p.validate(&limits), Ok(()));
    }

    #[test]
    fn incoherent_limits_validate_nothing() {
        let limits = FormationLimits {
            min_separation_m: 0.0,
            ..FormationLimits::default()
        };
        assert_eq!(
            program().validate(&limits),
            Err(FormationError::IncoherentLimits)
        );
    }
}
