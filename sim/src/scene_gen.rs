//! Procedurally generated scenes for evaluation, deterministic from a seed.
//!
//! Two kinds of airspace, as in the paper's evaluation split:
//! - **dense** ([`Airspace::Dense`]): a grid of city blocks separated by 12 m roads, tall
//!   buildings (12–60 m), some blocks split by narrow corridors, a water tower and
//!   billboard signs at the roadside;
//! - **open** ([`Airspace::Open`]): fields with a lake, a river crossed by a road on a
//!   bridge, a forest, a few low buildings, a water tower and billboard signs.
//!
//! Both start from a helipad at the origin. Landmarks an instruction can name are unique in
//! their scene: at most one red-, blue- and green-roofed building each, one water tower,
//! signs with distinct text, one lake, one bridge, one forest (an [`Area`]). Everything
//! else carries a `#` number in its name ([`Landmark::is_referable`]).
//!
//! The same `(airspace, seed)` always gives the same scene: the generator draws from
//! ChaCha8 (`rand_chacha`), whose output is portable across platforms and versions.

use crate::world::{Area, Landmark, LandmarkKind, World, lm, palette, patch, tree};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Texts the billboards carry (letters the renderer draws; the OCR role reads them).
pub const SIGN_TEXTS: [&str; 16] = [
    "LAKE VIEW",
    "HOTEL",
    "PARK",
    "CITY HALL",
    "MARKET",
    "STATION",
    "MUSEUM",
    "LIBRARY",
    "CAFE",
    "HARBOR",
    "PLAZA",
    "GARDEN",
    "BAKERY",
    "CINEMA",
    "SCHOOL",
    "STADIUM",
];

/// Distance between the centres of neighbouring city blocks (m).
pub const BLOCK_PITCH_M: f32 = 60.0;
/// Side of a city block (m); the rest of the pitch is road.
pub const BLOCK_SIDE_M: f32 = 48.0;
/// Blocks from the centre block to the edge of the city, each way.
pub const CITY_RADIUS_BLOCKS: i32 = 2;
/// Half the side of the open scene (m).
pub const OPEN_HALF_SIDE_M: f32 = 240.0;

/// The kind of airspace of a scene.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Airspace {
    /// Fields, lake, river and bridge, forest, sparse buildings.
    Open,
    /// City blocks, tall buildings, narrow corridors, roads.
    Dense,
}

impl Airspace {
    /// Both kinds, open first.
    pub const ALL: [Airspace; 2] = [Airspace::Open, Airspace::Dense];

    /// `open` or `dense`.
    pub fn as_str(self) -> &'static str {
        match self {
            Airspace::Open => "open",
            Airspace::Dense => "dense",
        }
    }

    /// The kind called `name` (`open` or `dense`).
    pub fn parse(name: &str) -> Option<Airspace> {
        match name {
            "open" => Some(Airspace::Open),
            "dense" => Some(Airspace::Dense),
            _ => None,
        }
    }
}

impl core::fmt::Display for Airspace {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A generated scene's identity: its airspace and seed; its name is `open-7`, `dense-42`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SceneId {
    /// Kind of airspace.
    pub airspace: Airspace,
    /// Seed of the generator.
    pub seed: u64,
}

impl SceneId {
    /// The scene named `<airspace>-<seed>`, e.g. `dense-42`; `None` for anything else.
    pub fn parse(name: &str) -> Option<SceneId> {
        let (kind, seed) = name.split_once('-')?;
        let airspace = Airspace::parse(kind)?;
        if seed.is_empty() || !seed.bytes().all(|b| b.is_ascii_digit()) {
            return None;
        }
        Some(SceneId {
            airspace,
            seed: seed.parse().ok()?,
        })
    }

    /// `<airspace>-<seed>`.
    pub fn name(&self) -> String {
        format!("{}-{}", self.airspace, self.seed)
    }
}

/// The scene `id` (deterministic).
pub fn generate(id: SceneId) -> World {
    // the airspace is mixed into the seed so open-7 and dense-7 share no draws
    let salt = match id.airspace {
        Airspace::Open => 0x6f70_656e,
        Airspace::Dense => 0x6465_6e73,
    };
    let mut rng = ChaCha8Rng::seed_from_u64(id.seed ^ (salt << 32));
    let (landmarks, areas) = match id.airspace {
        Airspace::Dense => dense(&mut rng),
        Airspace::Open => open(&mut rng),
    };
    World {
        name: id.name(),
        landmarks,
        areas,
    }
}

/// `k` distinct sign texts, in random order.
fn sign_texts(rng: &mut ChaCha8Rng, k: usize) -> Vec<&'static str> {
    let mut all = SIGN_TEXTS.to_vec();
    let mut out = Vec::with_capacity(k);
    for _ in 0..k.min(all.len()) {
        out.push(all.swap_remove(rng.random_range(0..all.len())));
    }
    out
}

/// A billboard 12 m wide and 8 m high standing on the ground, its text facing north/south
/// (`faces_north_south`) or east/west, centred at `(n, e)`.
fn billboard(text: &str, n: f32, e: f32, faces_north_south: bool) -> Landmark {
    let (dn, de) = if faces_north_south {
        (0.5, 6.0)
    } else {
        (6.0, 0.5)
    };
    lm(
        &format!("yellow sign that says {text}"),
        LandmarkKind::Sign { text: text.into() },
        [n - dn, e - de, 0.0],
        [n + dn, e + de, 8.0],
        palette::SIGN_YELLOW,
        palette::SIGN_YELLOW,
    )
}

/// The roof colour, wall colour and name of a building with a referable roof colour.
const ROOFS: [(&str, [u8; 3], [u8; 3]); 3] = [
    (
        "red-roofed building",
        palette::RED_ROOF,
        palette::BEIGE_WALL,
    ),
    (
        "blue-roofed building",
        palette::BLUE_ROOF,
        palette::GREY_WALL,
    ),
    (
        "green-roofed building",
        palette::GREEN_ROOF,
        palette::GREY_WALL,
    ),
];

fn building(name: &str, min: [f32; 3], max: [f32; 3], roof: usize) -> Landmark {
    let (wall, top) = match ROOFS.get(roof) {
        Some(r) => (r.2, r.1),
        None => (palette::GREY_WALL, palette::GREY_ROOF),
    };
    lm(name, LandmarkKind::Building, min, max, wall, top)
}

fn helipad() -> Landmark {
    patch(
        "helipad",
        LandmarkKind::Helipad,
        [-6.0, 6.0],
        [-6.0, 6.0],
        palette::HELIPAD,
    )
}

/// The city: blocks `(i, j)` centred at `(i, j) * BLOCK_PITCH_M`; the centre block is a
/// plaza with the helipad.
fn dense(rng: &mut ChaCha8Rng) -> (Vec<Landmark>, Vec<Area>) {
    let r = CITY_RADIUS_BLOCKS;
    let half_road = 0.5 * (BLOCK_PITCH_M - BLOCK_SIDE_M);
    let extent = (r as f32 + 0.5) * BLOCK_PITCH_M;
    let mut out = vec![helipad()];
    // roads between the blocks and around the city; intersections overlap (same colour)
    for k in -r - 1..=r {
        let c = (k as f32 + 0.5) * BLOCK_PITCH_M;
        let n = out.len();
        out.push(patch(
            &format!("road #{n}"),
            LandmarkKind::Road,
            [-extent - half_road, extent + half_road],
            [c - half_road, c + half_road],
            palette::ROAD,
        ));
        out.push(patch(
            &format!("road #{}", n + 1),
            LandmarkKind::Road,
            [c - half_road, c + half_road],
            [-extent - half_road, extent + half_road],
            palette::ROAD,
        ));
    }
    let mut blocks: Vec<(i32, i32)> = (-r..=r)
        .flat_map(|i| (-r..=r).map(move |j| (i, j)))
        .filter(|&b| b != (0, 0))
        .collect();
    // shuffle, then: the tower, the three coloured roofs, the signs take the first blocks
    for k in (1..blocks.len()).rev() {
        blocks.swap(k, rng.random_range(0..=k));
    }
    let texts = sign_texts(rng, 4);
    for (index, &(i, j)) in blocks.iter().enumerate() {
        let (cn, ce) = (i as f32 * BLOCK_PITCH_M, j as f32 * BLOCK_PITCH_M);
        let h = 0.5 * BLOCK_SIDE_M;
        if index == 0 {
            let height = rng.random_range(40.0..70.0f32);
            out.push(lm(
                "blue water tower",
                LandmarkKind::Tower,
                [cn - 4.0, ce - 4.0, 0.0],
                [cn + 4.0, ce + 4.0, height],
                palette::TOWER_BLUE,
                palette::TOWER_TOP,
            ));
            continue;
        }
        // a sign at the north or south edge of the block, facing the road
        if let Some(text) = texts.get(index.wrapping_sub(4)) {
            let north = rng.random_bool(0.5);
            let sn = if north { cn + h - 1.0 } else { cn - h + 1.0 };
            out.push(billboard(text, sn, ce, true));
        }
        let has_sign = index >= 4 && index < 4 + texts.len();
        // keep 4 m from the roads, and 4 m from a sign at the block edge
        let margin_n = if has_sign { 6.0 } else { 4.0 };
        let roof = if (1..=3).contains(&index) {
            index - 1
        } else {
            usize::MAX
        };
        let height = rng.random_range(12.0..60.0f32);
        let split = roof == usize::MAX && rng.random_bool(0.35);
        if split {
            // two buildings with a narrow east-west corridor between them
            let gap = rng.random_range(8.0..12.0f32);
            let at = ce + rng.random_range(-6.0..6.0f32);
            let h2 = rng.random_range(12.0..60.0f32);
            let n = out.len();
            out.push(building(
                &format!("grey building #{n}"),
                [cn - h + margin_n, ce - h + 4.0, 0.0],
                [cn + h - margin_n, at - 0.5 * gap, height],
                usize::MAX,
            ));
            out.push(building(
                &format!("grey building #{}", n + 1),
                [cn - h + margin_n, at + 0.5 * gap, 0.0],
                [cn + h - margin_n, ce + h - 4.0, h2],
                usize::MAX,
            ));
        } else {
            let sn = rng.random_range(14.0..(h - margin_n));
            let se = rng.random_range(14.0..(h - 4.0));
            let name = match ROOFS.get(roof) {
                Some(r) => r.0.to_string(),
                None => format!("grey building #{}", out.len()),
            };
            out.push(building(
                &name,
                [cn - sn, ce - se, 0.0],
                [cn + sn, ce + se, height],
                roof,
            ));
        }
    }
    (out, Vec::new())
}

/// Fields around the helipad: a lake, a river with a bridge, a forest, a few buildings,
/// a water tower and signs, each in its own sector so nothing overlaps.
fn open(rng: &mut ChaCha8Rng) -> (Vec<Landmark>, Vec<Area>) {
    let mut out = vec![helipad()];
    let mut areas = Vec::new();
    let half = OPEN_HALF_SIDE_M;
    // the river runs north-south east of the helipad, or west; a road crosses it on a bridge
    let east = rng.random_bool(0.5);
    let side = if east { 1.0 } else { -1.0 };
    let river_e = side * rng.random_range(110.0..150.0f32);
    let river_w = 20.0;
    let (r0, r1) = (river_e - 0.5 * river_w, river_e + 0.5 * river_w);
    let road_n = rng.random_range(-60.0..60.0f32);
    out.push(patch(
        "river #1",
        LandmarkKind::Water,
        [-half, road_n - 6.0],
        [r0, r1],
        palette::WATER,
    ));
    out.push(patch(
        "river #2",
        LandmarkKind::Water,
        [road_n + 6.0, half],
        [r0, r1],
        palette::WATER,
    ));
    // the road from the helipad to the river and beyond, interrupted where the bridge is
    let (near, far) = if east {
        ([8.0, r0 - 6.0], [r1 + 6.0, half])
    } else {
        ([r1 + 6.0, -8.0], [-half, r0 - 6.0])
    };
    out.push(patch(
        "road #1",
        LandmarkKind::Road,
        [road_n - 5.0, road_n + 5.0],
        near,
        palette::ROAD,
    ));
    out.push(patch(
        "road #2",
        LandmarkKind::Road,
        [road_n - 5.0, road_n + 5.0],
        far,
        palette::ROAD,
    ));
    out.push(lm(
        "bridge",
        LandmarkKind::Bridge,
        [road_n - 6.0, r0 - 6.0, 0.0],
        [road_n + 6.0, r1 + 6.0, 3.0],
        palette::BRIDGE,
        palette::BRIDGE,
    ));
    // the other side of the helipad: north-west/south-west (or east) sectors
    let other = -side;
    let north = rng.random_bool(0.5);
    let ns = if north { 1.0 } else { -1.0 };
    // lake: on the far side from the river, north or south
    let lake_n = ns * rng.random_range(90.0..150.0f32);
    let lake_e = other * rng.random_range(60.0..120.0f32);
    let (ln, le) = (
        rng.random_range(25.0..45.0f32),
        rng.random_range(30.0..55.0f32),
    );
    out.push(patch(
        "lake",
        LandmarkKind::Water,
        [lake_n - ln, lake_n + ln],
        [lake_e - le, lake_e + le],
        palette::WATER,
    ));
    // forest: the opposite north/south half, same side
    let forest_n = -ns * rng.random_range(80.0..140.0f32);
    let forest_e = other * rng.random_range(50.0..110.0f32);
    let trees = rng.random_range(14..22);
    let mut placed: Vec<[f32; 2]> = Vec::new();
    for _ in 0..trees * 4 {
        if placed.len() == trees {
            break;
        }
        let p = [
            forest_n + rng.random_range(-30.0..30.0f32),
            forest_e + rng.random_range(-30.0..30.0f32),
        ];
        if placed
            .iter()
            .all(|q| (q[0] - p[0]).abs() > 6.0 || (q[1] - p[1]).abs() > 6.0)
        {
            placed.push(p);
            let n = out.len();
            out.push(tree(
                &format!("tree #{n}"),
                p[0] - 2.0,
                p[1] - 2.0,
                rng.random_range(8.0..14.0f32),
            ));
        }
    }
    areas.push(Area {
        name: "forest".into(),
        min: [forest_n - 32.0, forest_e - 32.0],
        max: [forest_n + 32.0, forest_e + 32.0],
    });
    // buildings along the road on the helipad's side of the river, plus the tower
    let texts = sign_texts(rng, 3);
    let mut along: Vec<f32> = Vec::new();
    let lo = 30.0f32;
    let hi = river_e.abs() - 30.0;
    for k in 0..4 {
        // four slots along the road, alternately north and south of it
        let e = side * (lo + (hi - lo) * (k as f32 + 0.5) / 4.0);
        along.push(e);
        let off = if k % 2 == 0 { 1.0 } else { -1.0 };
        let (bn, be) = (road_n + off * rng.random_range(22.0..32.0f32), e);
        let (sn, se) = (rng.random_range(5.0..8.0f32), rng.random_range(5.0..8.0f32));
        let height = rng.random_range(8.0..20.0f32);
        let roof = if k < 3 { k } else { usize::MAX };
        let name = match ROOFS.get(roof) {
            Some(r) => r.0.to_string(),
            None => format!("grey building #{}", out.len()),
        };
        out.push(building(
            &name,
            [bn - sn, be - se, 0.0],
            [bn + sn, be + se, height],
            roof,
        ));
    }
    // the water tower beyond the river
    let tn = road_n + if rng.random_bool(0.5) { 40.0 } else { -40.0 };
    let te = river_e + side * rng.random_range(40.0..70.0f32);
    out.push(lm(
        "blue water tower",
        LandmarkKind::Tower,
        [tn - 4.0, te - 4.0, 0.0],
        [tn + 4.0, te + 4.0, rng.random_range(24.0..36.0f32)],
        palette::TOWER_BLUE,
        palette::TOWER_TOP,
    ));
    // signs: by the lake shore, by the forest edge, and by the road across the river
    out.push(billboard(texts[0], lake_n - ns * (ln + 10.0), lake_e, true));
    out.push(billboard(texts[1], forest_n + ns * 40.0, forest_e, true));
    out.push(billboard(
        texts[2],
        road_n + 14.0,
        river_e + side * 30.0,
        true,
    ));
    (out, areas)
}
