//! The episode generator: multi-step instructions over generated scenes, with a
//! collision-free reference trajectory and the subgoal segmentation.
//!
//! An episode takes off from the helipad to a cruise altitude, visits one to three
//! landmarks an instruction can name ("fly to the red-roofed building", "fly over the
//! bridge", "turn left and fly to the blue water tower") and lands next to a last one
//! ("land next to the yellow sign that says HOTEL"). Between landmarks the reference path
//! is the shortest 8-connected path on a 2 m grid of the cells that keep
//! [`CLEARANCE_M`] from every obstacle reaching within [`VERTICAL_CLEARANCE_M`] of the
//! cruise altitude (A*), shortened by line-of-sight and resampled at AerialVLN's 5 m step.
//! Climbs and descents are vertical, in 2 m steps.
//!
//! Splits: every split has its own scenes, so `val_unseen` and `test_unseen` are flown in
//! scenes no `train` episode uses ([`Split::scene_seeds`]).

use crate::episode::{Episode, Goal, Instruction, SubgoalAnnotation};
use aeris_geometry::wrap_pi;
use aeris_sim::scene_gen::{Airspace, SceneId};
use aeris_sim::world::{Extent, Landmark, LandmarkKind, World};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Horizontal distance every reference position keeps from obstacles (m).
pub const CLEARANCE_M: f32 = 5.0;
/// Obstacles whose top is within this of the cruise altitude (or above it) are avoided
/// horizontally (m).
pub const VERTICAL_CLEARANCE_M: f32 = 4.0;
/// Horizontal step of the reference path (m): AerialVLN's forward action.
pub const STEP_M: f32 = 5.0;
/// Vertical step of the reference path (m): AerialVLN's up/down action.
pub const CLIMB_STEP_M: f32 = 2.0;
/// Grid cell of the path search (m).
pub const GRID_M: f32 = 2.0;
/// Distance (m) between a named landmark's footprint and the point the path goes to.
pub const APPROACH_M: f32 = 12.0;
/// Least distance (m) between the centres of consecutive targets (the helipad first), and
/// between the helipad and the last target.
pub const MIN_LEG_M: f32 = 50.0;
/// Landing points keep this far from obstacles and water (m).
pub const LANDING_CLEARANCE_M: f32 = 6.0;

/// A dataset split.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Split {
    /// Training scenes.
    Train,
    /// Validation on scenes not in train.
    ValUnseen,
    /// Test on scenes not in train or validation.
    TestUnseen,
}

impl Split {
    /// Every split.
    pub const ALL: [Split; 3] = [Split::Train, Split::ValUnseen, Split::TestUnseen];

    /// `train`, `val_unseen`, `test_unseen`.
    pub fn as_str(self) -> &'static str {
        match self {
            Split::Train => "train",
            Split::ValUnseen => "val_unseen",
            Split::TestUnseen => "test_unseen",
        }
    }

    /// The split called `name`.
    pub fn parse(name: &str) -> Option<Split> {
        Split::ALL.into_iter().find(|s| s.as_str() == name)
    }

    /// The split whose scenes include `scene_id` (`open-1003`, `dense-2001`: an airspace and
    /// a seed), if any.
    pub fn of_scene(scene_id: &str) -> Option<Split> {
        let seed: u64 = scene_id.rsplit('-').next()?.parse().ok()?;
        Split::ALL
            .into_iter()
            .find(|s| s.scene_seeds().contains(&seed))
    }

    /// Seeds of this split's scenes (each seed is a scene of both airspaces): train
    /// 1000..1012, val_unseen 2000..2004, test_unseen 3000..3004 — disjoint.
    pub fn scene_seeds(self) -> core::ops::Range<u64> {
        match self {
            Split::Train => 1000..1012,
            Split::ValUnseen => 2000..2004,
            Split::TestUnseen => 3000..3004,
        }
    }
}

/// Which airspaces a split's episodes come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AirspaceFilter {
    /// Open only.
    Open,
    /// Dense only.
    Dense,
    /// Both, alternating.
    Full,
}

impl AirspaceFilter {
    /// `open`, `dense` or `full`.
    pub fn parse(name: &str) -> Option<AirspaceFilter> {
        match name {
            "open" => Some(AirspaceFilter::Open),
            "dense" => Some(AirspaceFilter::Dense),
            "full" => Some(AirspaceFilter::Full),
            _ => None,
        }
    }

    fn kinds(self) -> &'static [Airspace] {
        match self {
            AirspaceFilter::Open => &[Airspace::Open],
            AirspaceFilter::Dense => &[Airspace::Dense],
            AirspaceFilter::Full => &Airspace::ALL,
        }
    }
}

/// Why episodes could not be generated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GenerateError {
    /// No collision-free episode was found in a scene after many tries (a generator bug:
    /// every built-in scene has some).
    #[error("no collision-free episode found in scene {scene} after {tries} tries")]
    NoEpisode {
        /// The scene.
        scene: String,
        /// Tries made.
        tries: usize,
    },
}

/// The first `count` episodes of `split` over `airspaces`: scenes are taken in turn
/// (alternating airspaces for `Full`), episode `k` of a scene seeded by `(scene, k)`.
/// Deterministic; `progress(done, count)` is called after each episode.
pub fn generate_split(
    split: Split,
    airspaces: AirspaceFilter,
    count: usize,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Vec<Episode>, GenerateError> {
    let seeds: Vec<u64> = split.scene_seeds().collect();
    let kinds = airspaces.kinds();
    let scenes: Vec<SceneId> = seeds
        .iter()
        .flat_map(|&seed| {
            kinds
                .iter()
                .map(move |&airspace| SceneId { airspace, seed })
        })
        .collect();
    let mut worlds: Vec<Option<World>> = vec![None; scenes.len()];
    let mut out = Vec::with_capacity(count);
    for k in 0..count {
        let s = k % scenes.len();
        let round = k / scenes.len();
        let world = worlds[s].get_or_insert_with(|| aeris_sim::scene_gen::generate(scenes[s]));
        let id = format!("{}-{}-{round}", split.as_str(), scenes[s].name());
        out.push(generate_episode(world, scenes[s], &id, round as u64)?);
        progress(k + 1, count);
    }
    Ok(out)
}

/// What a leg of an episode goes to.
#[derive(Debug, Clone)]
struct Target {
    /// How the instruction names it ("the red-roofed building").
    phrase: String,
    /// Landmark or area name.
    name: String,
    /// Fly over it (lake, bridge, forest) rather than beside it.
    over: bool,
    /// Footprint `[min N, min E, max N, max E]`.
    rect: [f32; 4],
}

fn targets(world: &World) -> Vec<Target> {
    let mut out: Vec<Target> = world
        .landmarks
        .iter()
        .filter(|l| l.is_referable() && !matches!(l.kind, LandmarkKind::Helipad))
        .filter_map(|l| {
            let (phrase, over) = match &l.kind {
                LandmarkKind::Water | LandmarkKind::Bridge => (format!("the {}", l.name), true),
                LandmarkKind::Building | LandmarkKind::Tower | LandmarkKind::Sign { .. } => {
                    (format!("the {}", l.name), false)
                }
                _ => return None,
            };
            Some(Target {
                phrase,
                name: l.name.clone(),
                over,
                rect: [l.min[0], l.min[1], l.max[0], l.max[1]],
            })
        })
        .collect();
    out.extend(world.areas.iter().map(|a| Target {
        phrase: format!("the {}", a.name),
        name: a.name.clone(),
        over: true,
        rect: [a.min[0], a.min[1], a.max[0], a.max[1]],
    }));
    out
}

/// One episode in `world`, or an error when no collision-free one is found.
pub fn generate_episode(
    world: &World,
    scene: SceneId,
    id: &str,
    seed: u64,
) -> Result<Episode, GenerateError> {
    const TRIES: usize = 64;
    let mut rng = ChaCha8Rng::seed_from_u64(scene.seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ seed);
    let all = targets(world);
    for _ in 0..TRIES {
        if let Some(e) = try_episode(world, scene, id, &all, &mut rng) {
            return Ok(e);
        }
    }
    Err(GenerateError::NoEpisode {
        scene: scene.name(),
        tries: TRIES,
    })
}

/// The free-cell grid at one altitude.
struct Grid {
    origin: [f32; 2],
    cols: i32,
    rows: i32,
    free: Vec<bool>,
}

impl Grid {
    fn new(world: &World, altitude: f32) -> Grid {
        // the scene and at least 20 m around the start, with 40 m to go round obstacles
        let mut x = Extent::around([-20.0, -20.0, 0.0]);
        x.include([20.0, 20.0, 0.0]);
        if let Some(w) = world.extent() {
            x.union(&w);
        }
        let (lo, hi) = (
            [x.min[0] - 40.0, x.min[1] - 40.0],
            [x.max[0] + 40.0, x.max[1] + 40.0],
        );
        let rows = ((hi[0] - lo[0]) / GRID_M).ceil() as i32;
        let cols = ((hi[1] - lo[1]) / GRID_M).ceil() as i32;
        let blocking: Vec<&Landmark> = world
            .landmarks
            .iter()
            .filter(|l| l.is_obstacle() && l.max[2] > altitude - VERTICAL_CLEARANCE_M)
            .collect();
        let mut free = vec![true; (rows * cols) as usize];
        for r in 0..rows {
            for c in 0..cols {
                let (n, e) = (
                    lo[0] + (r as f32 + 0.5) * GRID_M,
                    lo[1] + (c as f32 + 0.5) * GRID_M,
                );
                // half a cell of margin so every point of a free cell keeps the clearance
                free[(r * cols + c) as usize] = blocking
                    .iter()
                    .all(|l| l.horizontal_distance(n, e) > CLEARANCE_M + 0.75 * GRID_M);
            }
        }
        Grid {
            origin: lo,
            cols,
            rows,
            free,
        }
    }

    fn cell(&self, p: [f32; 2]) -> Option<(i32, i32)> {
        let r = ((p[0] - self.origin[0]) / GRID_M).floor() as i32;
        let c = ((p[1] - self.origin[1]) / GRID_M).floor() as i32;
        (r >= 0 && c >= 0 && r < self.rows && c < self.cols).then_some((r, c))
    }

    fn centre(&self, (r, c): (i32, i32)) -> [f32; 2] {
        [
            self.origin[0] + (r as f32 + 0.5) * GRID_M,
            self.origin[1] + (c as f32 + 0.5) * GRID_M,
        ]
    }

    fn is_free(&self, (r, c): (i32, i32)) -> bool {
        r >= 0
            && c >= 0
            && r < self.rows
            && c < self.cols
            && self.free[(r * self.cols + c) as usize]
    }

    /// Shortest 8-connected path of free cells from `a` to `b` (their centres, with the
    /// exact end points at both ends).
    fn path(&self, a: [f32; 2], b: [f32; 2]) -> Option<Vec<[f32; 2]>> {
        let (start, goal) = (self.cell(a)?, self.cell(b)?);
        if !self.is_free(start) || !self.is_free(goal) {
            return None;
        }
        let (cells, _) = pathfinding::prelude::astar(
            &start,
            |&(r, c)| {
                let mut next = Vec::with_capacity(8);
                for (dr, dc, cost) in [
                    (1, 0, 10),
                    (-1, 0, 10),
                    (0, 1, 10),
                    (0, -1, 10),
                    (1, 1, 14),
                    (1, -1, 14),
                    (-1, 1, 14),
                    (-1, -1, 14),
                ] {
                    let n = (r + dr, c + dc);
                    // diagonal moves may not cut a blocked corner
                    if self.is_free(n) && self.is_free((r + dr, c)) && self.is_free((r, c + dc)) {
                        next.push((n, cost));
                    }
                }
                next
            },
            |&(r, c)| {
                let (dr, dc) = ((r - goal.0).abs(), (c - goal.1).abs());
                10 * dr.max(dc) + 4 * dr.min(dc)
            },
            |&p| p == goal,
        )?;
        let mut pts: Vec<[f32; 2]> = cells.iter().map(|&c| self.centre(c)).collect();
        pts[0] = a;
        if let Some(last) = pts.last_mut() {
            *last = b;
        }
        Some(self.shorten(&pts))
    }

    /// `true` when the segment `a`-`b` crosses free cells only (sampled every 0.5 m).
    fn visible(&self, a: [f32; 2], b: [f32; 2]) -> bool {
        let len = (b[0] - a[0]).hypot(b[1] - a[1]);
        let n = (len / 0.5).ceil().max(1.0) as usize;
        (0..=n).all(|i| {
            let t = i as f32 / n as f32;
            self.cell([a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t])
                .is_some_and(|c| self.is_free(c))
        })
    }

    /// Line-of-sight shortening: from each kept point, jump to the farthest visible one.
    fn shorten(&self, pts: &[[f32; 2]]) -> Vec<[f32; 2]> {
        let mut out = vec![pts[0]];
        let mut i = 0;
        while i + 1 < pts.len() {
            let mut j = pts.len() - 1;
            while j > i + 1 && !self.visible(pts[i], pts[j]) {
                j -= 1;
            }
            out.push(pts[j]);
            i = j;
        }
        out
    }
}

/// Where a leg to `t` ends, seen from `from`: over its centre, or the free point at
/// [`APPROACH_M`] from its footprint nearest to `from`.
fn approach(grid: &Grid, t: &Target, from: [f32; 2]) -> Option<[f32; 2]> {
    let centre = [0.5 * (t.rect[0] + t.rect[2]), 0.5 * (t.rect[1] + t.rect[3])];
    if t.over {
        // over its centre, or the free cell of its footprint nearest to the centre
        let (lo, hi) = (
            grid.cell([t.rect[0], t.rect[1]])?,
            grid.cell([t.rect[2], t.rect[3]])?,
        );
        return (lo.0..=hi.0)
            .flat_map(|r| (lo.1..=hi.1).map(move |c| (r, c)))
            .filter(|&c| grid.is_free(c))
            .map(|c| grid.centre(c))
            .min_by(|a, b| dist2(*a, centre).total_cmp(&dist2(*b, centre)));
    }
    ring(t, APPROACH_M)
        .into_iter()
        .filter(|&p| grid.cell(p).is_some_and(|c| grid.is_free(c)))
        .min_by(|a, b| dist2(*a, from).total_cmp(&dist2(*b, from)))
}

/// 24 points around `t`'s footprint at horizontal distance `d`.
fn ring(t: &Target, d: f32) -> Vec<[f32; 2]> {
    let centre = [0.5 * (t.rect[0] + t.rect[2]), 0.5 * (t.rect[1] + t.rect[3])];
    let (hn, he) = (0.5 * (t.rect[2] - t.rect[0]), 0.5 * (t.rect[3] - t.rect[1]));
    (0..24)
        .map(|k| {
            let a = k as f32 * core::f32::consts::TAU / 24.0;
            let (s, c) = a.sin_cos();
            // point on the box's boundary in direction a, pushed out by d
            let scale = 1.0 / (c.abs() / hn.max(1e-3)).max(s.abs() / he.max(1e-3));
            [centre[0] + c * (scale + d), centre[1] + s * (scale + d)]
        })
        .collect()
}

fn dist2(a: [f32; 2], b: [f32; 2]) -> f32 {
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)
}

/// Bearing (rad, 0 = north, clockwise) from `a` to `b`.
fn bearing(a: [f32; 2], b: [f32; 2]) -> f32 {
    (b[1] - a[1]).atan2(b[0] - a[0])
}

/// "turn left and " / "turn right and " / "" for a heading change from `from` to `to`.
fn turn_words(from: f32, to: f32) -> &'static str {
    // wrap_pi maps a half turn to -180 degrees; negated, a half turn is a right turn
    let d = -wrap_pi(from - to).to_degrees();
    if d > 35.0 {
        "turn right and "
    } else if d < -35.0 {
        "turn left and "
    } else {
        ""
    }
}

/// A landing point next to `t`: clear of obstacles and water by
/// [`LANDING_CLEARANCE_M`] from the ground to the cruise altitude, reachable on `grid`,
/// nearest to `from`.
fn landing(
    world: &World,
    grid: &Grid,
    t: &Target,
    from: [f32; 2],
    cruise: f32,
) -> Option<[f32; 2]> {
    let d = LANDING_CLEARANCE_M + 2.0;
    [d, d + 4.0, d + 8.0]
        .into_iter()
        .flat_map(|r| ring(t, r))
        .filter(|&p| grid.cell(p).is_some_and(|c| grid.is_free(c)))
        .filter(|&p| {
            world.landmarks.iter().all(|l| {
                !(l.is_obstacle() || matches!(l.kind, LandmarkKind::Water))
                    || l.horizontal_distance(p[0], p[1]) > LANDING_CLEARANCE_M
            }) && (0..=((cruise / 2.0) as i32))
                .all(|k| !world.collides([p[0], p[1], k as f32 * 2.0], LANDING_CLEARANCE_M - 1.0))
        })
        .min_by(|a, b| dist2(*a, from).total_cmp(&dist2(*b, from)))
}

fn try_episode(
    world: &World,
    scene: SceneId,
    id: &str,
    all: &[Target],
    rng: &mut ChaCha8Rng,
) -> Option<Episode> {
    let cruise = match scene.airspace {
        Airspace::Open => rng.random_range(15..=25) as f32,
        Airspace::Dense => rng.random_range(20..=30) as f32,
    };
    let grid = Grid::new(world, cruise);
    let legs = rng.random_range(1..=3usize);
    // pick legs + 1 distinct targets; the last is where it lands (never over water)
    let mut pool: Vec<&Target> = all.iter().collect();
    let mut chosen: Vec<&Target> = Vec::new();
    let centre = |t: &Target| [0.5 * (t.rect[0] + t.rect[2]), 0.5 * (t.rect[1] + t.rect[3])];
    for k in 0..=legs {
        let last = k == legs;
        // every leg covers ground: the next target is MIN_LEG_M from the previous one
        let prev = chosen.last().map_or([0.0, 0.0], |t| centre(t));
        let candidates: Vec<usize> = (0..pool.len())
            .filter(|&i| !last || !pool[i].over)
            .filter(|&i| dist2(centre(pool[i]), prev) >= MIN_LEG_M * MIN_LEG_M)
            // and the goal is never near the start
            .filter(|&i| !last || dist2(centre(pool[i]), [0.0, 0.0]) >= MIN_LEG_M * MIN_LEG_M)
            .collect();
        if candidates.is_empty() {
            return None;
        }
        chosen.push(pool.swap_remove(candidates[rng.random_range(0..candidates.len())]));
    }
    let start_yaw = rng.random_range(0..4) as f32 * core::f32::consts::FRAC_PI_2;
    let start = [0.0f32, 0.0];
    // reference: climb, legs, approach to landing, descent
    let mut path: Vec<[f32; 4]> = Vec::new();
    let mut subgoals: Vec<SubgoalAnnotation> = Vec::new();
    let mut texts: Vec<String> = Vec::new();
    let mut u = 0.0;
    while u < cruise {
        path.push([start[0], start[1], u, start_yaw]);
        u += CLIMB_STEP_M;
    }
    path.push([start[0], start[1], cruise, start_yaw]);
    let text = format!("take off from the helipad to {cruise:.0} metres");
    subgoals.push(annotation(
        &text,
        "takeoff",
        [start[0], start[1], cruise],
        None,
        0,
        path.len() - 1,
    ));
    texts.push(text);
    let mut at = start;
    let mut heading = start_yaw;
    for (k, t) in chosen.iter().enumerate() {
        let last = k + 1 == chosen.len();
        let end = if last {
            landing(world, &grid, t, at, cruise)?
        } else {
            approach(&grid, t, at)?
        };
        let route = grid.path(at, end)?;
        let first = path.len();
        let first_bearing = bearing(route[0], route[route.len().min(2) - 1]);
        for w in route.windows(2) {
            let yaw = bearing(w[0], w[1]);
            let len = dist2(w[0], w[1]).sqrt();
            let n = (len / STEP_M).ceil().max(1.0) as usize;
            for i in 1..=n {
                let s = i as f32 / n as f32;
                path.push([
                    w[0][0] + (w[1][0] - w[0][0]) * s,
                    w[0][1] + (w[1][1] - w[0][1]) * s,
                    cruise,
                    yaw,
                ]);
            }
        }
        let turn = if route.len() >= 2 {
            turn_words(heading, first_bearing)
        } else {
            ""
        };
        if route.len() >= 2 {
            heading = bearing(route[route.len() - 2], route[route.len() - 1]);
        }
        let text = if last {
            format!("{turn}land next to {}", t.phrase)
        } else if t.over {
            format!("{turn}fly over {}", t.phrase)
        } else {
            format!("{turn}fly to {}", t.phrase)
        };
        if last {
            let mut u = cruise - CLIMB_STEP_M;
            while u > 0.0 {
                path.push([end[0], end[1], u, heading]);
                u -= CLIMB_STEP_M;
            }
            path.push([end[0], end[1], 0.0, heading]);
        }
        let waypoint = [end[0], end[1], if last { 0.0 } else { cruise }];
        let action = if last { "land" } else { "goto" };
        subgoals.push(annotation(
            &text,
            action,
            waypoint,
            Some(&t.name),
            first.min(path.len() - 1),
            path.len() - 1,
        ));
        texts.push(text);
        at = end;
    }
    let goal = path.last().map(|p| [p[0], p[1], p[2]])?;
    // an agent given the path as waypoints needs one per corner: a mission holds 16
    let positions: Vec<[f64; 3]> = path
        .iter()
        .map(|p| [round_cm(p[0]), round_cm(p[1]), round_cm(p[2])])
        .collect();
    if crate::mission::corners(&positions).len() > aeris_schemas::MAX_SUBGOALS {
        return None;
    }
    let instruction = sentence(&texts);
    let half = 0.5 * start_yaw as f64;
    Some(Episode {
        episode_id: id.to_string(),
        trajectory_id: id.to_string(),
        scene_id: scene.name(),
        start_position: [start[0] as f64, start[1] as f64, 0.0],
        // yaw about the up axis of [N, E, U]: clockwise seen from above is negative about U
        start_rotation: [half.cos(), 0.0, 0.0, -half.sin()],
        goals: vec![Goal {
            position: goal.map(round_cm),
            radius: Some(crate::metrics::SUCCESS_RADIUS_M),
        }],
        reference_path: path
            .iter()
            .map(|p| p.iter().map(|&x| round_cm(x)).collect())
            .collect(),
        instruction: Instruction {
            instruction_text: instruction,
        },
        airspace: Some(scene.airspace.as_str().to_string()),
        subgoals,
    })
}

fn round_cm(x: f32) -> f64 {
    (x as f64 * 100.0).round() / 100.0
}

fn annotation(
    text: &str,
    action: &str,
    waypoint: [f32; 3],
    landmark: Option<&str>,
    first: usize,
    last: usize,
) -> SubgoalAnnotation {
    SubgoalAnnotation {
        text: text.to_string(),
        action: action.to_string(),
        waypoint: waypoint.map(round_cm),
        landmark: landmark.map(str::to_string),
        reference_range: [first, last],
    }
}

/// "Take off ..., fly to ..., then land next to ...".
fn sentence(parts: &[String]) -> String {
    let mut s = String::new();
    for (i, p) in parts.iter().enumerate() {
        if i > 0 {
            s.push_str(if i + 1 == parts.len() {
                ", then "
            } else {
                ", "
            });
        }
        s.push_str(p);
    }
    if let Some(first) = s.get(0..1) {
        let up = first.to_uppercase();
        s.replace_range(0..1, &up);
    }
    s.push('.');
    s
}
