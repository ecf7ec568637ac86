//! Watching the vehicles of a flight of several (a formation): every vehicle's
//! `v{K}/vehicle/telemetry` -> its controller's tallies, the closest two vehicles came, and
//! collisions. A collision (two vehicles with live links closer than
//! [`COLLISION_DISTANCE_M`]) ends the flight as failed.

use crate::telemetry::{RestartSafeCounters, controller_counters, in_the_air};
use aeris_runtime::bus::{BusError, FlightBus, TypedSubscriber};
use aeris_schemas::{VehicleTelemetry, topics};
use serde::Serialize;

/// Two vehicles closer than this (m, centre to centre) have collided: two small
/// multirotors' spans.
pub const COLLISION_DISTANCE_M: f32 = 1.0;

/// Two vehicles that came too close.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Collision {
    /// The vehicles (1-based), lower first.
    pub vehicles: (u8, u8),
    /// How far apart they were (m).
    pub distance_m: f32,
    /// Where the first of them was `[N, E, U]`.
    pub position: [f32; 3],
}

/// One vehicle at the end of a flight.
#[derive(Debug, Clone, Serialize)]
pub struct VehicleSummary {
    /// Its number (1-based): its scope `v{K}`, its MAVLink system id.
    pub vehicle: u8,
    /// Its controller's ticks.
    pub controller_ticks: u64,
    /// Ticks that missed their deadline.
    pub controller_missed_ticks: u64,
    /// Setpoints its controller refused (invalid).
    pub setpoints_refused: u64,
    /// Ticks it held without a fresh setpoint.
    pub hold_ticks: u64,
    /// Where it was last `[N, E, U]`.
    pub final_position: Option<[f32; 3]>,
    /// It flew, and was on the ground at the end.
    pub landed_after_flight: bool,
    /// Its controller had no autopilot link at the end (its vehicle lost).
    pub link_lost: bool,
}

/// What the formation role reports in its heartbeat (`aeris_roles::formation_role`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct FormationTally {
    /// The phase flown (1-based; 0 before it flies).
    pub phase: u64,
    /// What its executor does: `waiting`, `flying`, `settling`, `done`, `stuck`.
    pub state: &'static str,
    /// Vehicles that left the formation (lost, or off their slot), each one replanned
    /// around.
    pub replans: u64,
    /// Setpoints it published.
    pub setpoints: u64,
    /// The longest wait at a phase's end until every vehicle was within tolerance of its
    /// slot (ms).
    pub settle_max_ms: u64,
    /// Vehicles in the formation.
    pub in_formation: u64,
    /// Slots the hub's program gate refused to bind (never sent; that controller held).
    pub refused_slots: u64,
    /// The first program's time to write, check and repair (ms).
    pub program_ms: u64,
}

impl FormationTally {
    /// Read from the formation role's heartbeat counters.
    pub fn from_counters(c: [u64; 8]) -> Self {
        Self {
            phase: c[0],
            state: match c[1] {
                1 => "flying",
                2 => "settling",
                3 => "done",
                4 => "stuck",
                _ => "waiting",
            },
            replans: c[2],
            setpoints: c[3],
            settle_max_ms: c[4],
            in_formation: c[5],
            refused_slots: c[7],
            program_ms: c[6],
        }
    }
}

/// The vehicles of a flight at its end.
#[derive(Debug, Clone, Serialize)]
pub struct FleetSummary {
    /// Each vehicle, vehicle 1 first.
    pub vehicles: Vec<VehicleSummary>,
    /// The closest two vehicles with live links came, by their telemetry (m).
    pub min_separation_m: Option<f32>,
    /// The vehicles of that closest approach (1-based).
    pub closest_pair: Option<(u8, u8)>,
    /// The first collision, if any.
    pub collision: Option<Collision>,
    /// The formation role's last report.
    pub formation: Option<FormationTally>,
}

struct VehicleWatch {
    number: u8,
    telemetry: TypedSubscriber<VehicleTelemetry>,
    controller: RestartSafeCounters<4>,
    last: Option<VehicleTelemetry>,
    flew: bool,
}

/// Subscribes to every vehicle's telemetry and keeps the tallies.
pub struct FleetMonitor {
    vehicles: Vec<VehicleWatch>,
    closest: Option<(f32, (u8, u8))>,
    collision: Option<Collision>,
}

impl FleetMonitor {
    /// Watch vehicles `1..=vehicles` of the flight on `bus`.
    pub fn new(bus: &FlightBus, vehicles: u8) -> Result<Self, BusError> {
        let vehicles = (1..=vehicles)
            .map(|k| {
                Ok(VehicleWatch {
                    number: k,
                    telemetry: bus.subscriber_in::<topics::VehicleTelemetry>(Some(k))?,
                    controller: RestartSafeCounters::default(),
                    last: None,
                    flew: false,
                })
            })
            .collect::<Result<Vec<_>, BusError>>()?;
        Ok(Self {
            vehicles,
            closest: None,
            collision: None,
        })
    }

    /// Take every vehicle's newest telemetry; the closest pair and any collision.
    pub fn poll(&mut self) -> Result<(), BusError> {
        for v in &mut self.vehicles {
            if let Some(t) = v.telemetry.latest()?
                && t.validate().is_ok()
            {
                v.controller.update(t.seq, controller_counters(&t));
                v.flew |= in_the_air(&t);
                v.last = Some(t);
            }
        }
        let linked: Vec<(u8, [f32; 3])> = self
            .vehicles
            .iter()
            .filter_map(|v| {
                v.last
                    .filter(|t| t.link_up == 1)
                    .map(|t| (v.number, t.position))
            })
            .collect();
        for (i, (a, pa)) in linked.iter().enumerate() {
            for (b, pb) in &linked[i + 1..] {
                let d = (0..3).map(|j| (pa[j] - pb[j]).powi(2)).sum::<f32>().sqrt();
                if self.closest.is_none_or(|(c, _)| d < c) {
                    self.closest = Some((d, (*a, *b)));
                }
                if d < COLLISION_DISTANCE_M && self.collision.is_none() {
                    self.collision = Some(Collision {
                        vehicles: (*a, *b),
                        distance_m: d,
                        position: *pa,
                    });
                }
            }
        }
        Ok(())
    }

    /// The first collision, if any.
    pub fn collision(&self) -> Option<Collision> {
        self.collision
    }

    /// Every vehicle whose controller still has its autopilot is on the ground, after at
    /// least one flew: the formation has landed (a vehicle the program did not fly stayed
    /// on the ground).
    pub fn all_landed_after_flight(&self) -> bool {
        let linked = || {
            self.vehicles
                .iter()
                .filter_map(|v| v.last.map(|t| (v, t)))
                .filter(|(_, t)| t.link_up == 1)
        };
        linked().any(|(v, _)| v.flew) && linked().all(|(_, t)| t.landed == 1)
    }

    /// Where each vehicle is (vehicle 1 first; `None` before its first telemetry).
    pub fn positions(&self) -> Vec<Option<[f32; 3]>> {
        self.vehicles
            .iter()
            .map(|v| v.last.map(|t| t.position))
            .collect()
    }

    /// The tallies so far.
    pub fn summary(&self) -> FleetSummary {
        FleetSummary {
            vehicles: self
                .vehicles
                .iter()
                .map(|v| VehicleSummary {
                    vehicle: v.number,
                    controller_ticks: v.controller.total(0),
                    controller_missed_ticks: v.controller.total(1),
                    setpoints_refused: v.controller.total(2),
                    hold_ticks: v.controller.total(3),
                    final_position: v.last.map(|t| t.position),
                    landed_after_flight: v.flew && v.last.is_some_and(|t| t.landed == 1),
                    link_lost: v.last.is_some_and(|t| t.link_up == 0),
                })
                .collect(),
            min_separation_m: self.closest.map(|(d, _)| d),
            closest_pair: self.closest.map(|(_, p)| p),
            collision: self.collision,
            formation: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn telemetry(seq: u64, position: [f32; 3], landed: bool) -> VehicleTelemetry {
        VehicleTelemetry {
            seq,
            stamp_ns: 1,
            link_up: 1,
            armed: u8::from(!landed),
            landed: u8::from(landed),
            position,
            ..VehicleTelemetry::default()
        }
    }

    #[test]
    fn two_vehicles_under_a_metre_apart_collide_and_a_lost_one_is_not_counted() {
        let flight = format!("t-fleet-{}", std::process::id());
        let watcher = FlightBus::builder(&flight).node_name("w").create().unwrap();
        let mut fleet = FleetMonitor::new(&watcher, 3).unwrap();
        let vehicle = |k: u8| {
            let bus = FlightBus::builder(&flight)
                .node_name(&format!("c{k}"))
                .vehicle(Some(k))
                .create()
                .unwrap();
            let publisher = bus.publisher::<topics::VehicleTelemetry>().unwrap();
            (bus, publisher)
        };
        let (_b1, v1) = vehicle(1);
        let (_b2, v2) = vehicle(2);
        let (_b3, v3) = vehicle(3);
        v1.publish(&telemetry(1, [0.0, 0.0, 5.0], false)).unwrap();
        v2.publish(&telemetry(1, [0.0, 3.0, 5.0], false)).unwrap();
        // vehicle 3's controller lost its autopilot: where it was last is not where it is
        let mut lost = telemetry(1, [0.0, 0.5, 5.0], false);
        lost.link_up = 0;
        v3.publish(&lost).unwrap();
        fleet.poll().unwrap();
        assert_eq!(fleet.collision(), None);
        assert_eq!(fleet.summary().min_separation_m, Some(3.0));
        assert!(!fleet.all_landed_after_flight());
        v2.publish(&telemetry(2, [0.0, 0.6, 5.0], false)).unwrap();
        fleet.poll().unwrap();
        let c = fleet.collision().expect("a collision");
        assert_eq!(c.vehicles, (1, 2));
        assert!((c.distance_m - 0.6).abs() < 1e-5);
        // both on the ground: landed (the lost one does not hold the flight up)
        v1.publish(&telemetry(2, [0.0, 0.0, 0.0], true)).unwrap();
        v2.publish(&telemetry(3, [0.0, 3.0, 0.0], true)).unwrap();
        fleet.poll().unwrap();
        assert!(fleet.all_landed_after_flight());
        let s = fleet.summary();
        assert!(s.vehicles[2].link_lost && !s.vehicles[2].landed_after_flight);
        assert!(s.vehicles[0].landed_after_flight && s.vehicles[1].landed_after_flight);
    }
}
