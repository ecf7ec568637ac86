//! Built-in worlds: scenes of axis-aligned boxes with named landmarks.
//!
//! Coordinates are `[N, E, U]` metres (north, east, up). The ground is the plane `U = 0`,
//! covered with grass except where a ground patch (road, water, helipad: a box with
//! `U` in `0..0.05`) lies on it. Every other landmark is an obstacle.
//!
//! The colours of the built-in worlds come from [`palette`]; every class of landmark has
//! its own colour, so a colour segmenter can tell them apart (see `aeris-roles`'
//! geometric perception).

/// Colours of the built-in worlds (sRGB, 8 bits per channel).
///
/// Each entry is distinct from every other, including after the renderer's face shading
/// ([`crate::render::FACE_SHADES`]), so a pixel's colour names its class.
pub mod palette {
    /// Bare ground.
    pub const GRASS: [u8; 3] = [96, 140, 68];
    /// Helipad surface (white, slightly yellow).
    pub const HELIPAD: [u8; 3] = [228, 222, 176];
    /// Asphalt.
    pub const ROAD: [u8; 3] = [62, 64, 74];
    /// Walls of the grey buildings.
    pub const GREY_WALL: [u8; 3] = [172, 166, 156];
    /// Roofs of the grey buildings.
    pub const GREY_ROOF: [u8; 3] = [118, 114, 110];
    /// Walls of the red-roofed building.
    pub const BEIGE_WALL: [u8; 3] = [222, 200, 150];
    /// The red roof.
    pub const RED_ROOF: [u8; 3] = [186, 48, 38];
    /// Walls of the water tower.
    pub const TOWER_BLUE: [u8; 3] = [42, 84, 204];
    /// Top of the water tower.
    pub const TOWER_TOP: [u8; 3] = [70, 112, 226];
    /// Lake water.
    pub const WATER: [u8; 3] = [48, 118, 150];
    /// Sign board.
    pub const SIGN_YELLOW: [u8; 3] = [244, 212, 24];
    /// Lettering on signs.
    pub const SIGN_TEXT: [u8; 3] = [24, 24, 28];
    /// Sides of tree crowns.
    pub const TREE_SIDE: [u8; 3] = [46, 108, 42];
    /// Tops of tree crowns.
    pub const TREE_TOP: [u8; 3] = [52, 128, 48];
    /// Blue roofs (generated scenes).
    pub const BLUE_ROOF: [u8; 3] = [30, 40, 235];
    /// Green roofs (generated scenes).
    pub const GREEN_ROOF: [u8; 3] = [20, 220, 140];
    /// Bridge deck and sides (generated scenes).
    pub const BRIDGE: [u8; 3] = [200, 60, 190];
}

/// `Hit::landmark` value of a ray that hit bare ground (grass), not a landmark.
pub const GROUND: usize = usize::MAX;

/// Height (m) of ground patches: boxes lower than this are flat ground, not obstacles.
pub const GROUND_PATCH_MAX_U: f32 = 0.05;

/// What a landmark is.
#[derive(Debug, Clone, PartialEq)]
pub enum LandmarkKind {
    /// A building (walls and a roof).
    Building,
    /// A tower (e.g. a water tower).
    Tower,
    /// A sign board carrying `text`.
    Sign {
        /// The text painted on both faces of the board.
        text: String,
    },
    /// A road (ground patch).
    Road,
    /// Water (ground patch).
    Water,
    /// A helipad (ground patch).
    Helipad,
    /// A tree (a box crown).
    Tree,
    /// A bridge deck (an obstacle box over water or a road).
    Bridge,
}

impl LandmarkKind {
    /// `true` for ground patches (road, water, helipad): flat, never an obstacle.
    pub fn is_ground(&self) -> bool {
        matches!(
            self,
            LandmarkKind::Road | LandmarkKind::Water | LandmarkKind::Helipad
        )
    }
}

/// One named landmark: an axis-aligned box.
#[derive(Debug, Clone, PartialEq)]
pub struct Landmark {
    /// Human name, unique in its world, e.g. "red-roofed building". A name with a `#`
    /// ("grey building #3") is not one an instruction can refer to: others look the same
    /// (see [`Landmark::is_referable`]).
    pub name: String,
    /// What it is.
    pub kind: LandmarkKind,
    /// Lower corner `[N, E, U]` (m).
    pub min: [f32; 3],
    /// Upper corner `[N, E, U]` (m).
    pub max: [f32; 3],
    /// Colour of the side faces.
    pub wall: [u8; 3],
    /// Colour of the top face.
    pub roof: [u8; 3],
}

impl Landmark {
    /// Centre of the box `[N, E, U]`.
    pub fn centre(&self) -> [f32; 3] {
        [
            0.5 * (self.min[0] + self.max[0]),
            0.5 * (self.min[1] + self.max[1]),
            0.5 * (self.min[2] + self.max[2]),
        ]
    }

    /// `true` when the horizontal point `(n, e)` lies over the box (edges included).
    pub fn covers(&self, n: f32, e: f32) -> bool {
        n >= self.min[0] && n <= self.max[0] && e >= self.min[1] && e <= self.max[1]
    }

    /// Horizontal distance (m) from `(n, e)` to the box footprint (0 inside).
    pub fn horizontal_distance(&self, n: f32, e: f32) -> f32 {
        let dn = (self.min[0] - n).max(0.0).max(n - self.max[0]);
        let de = (self.min[1] - e).max(0.0).max(e - self.max[1]);
        (dn * dn + de * de).sqrt()
    }

    /// `true` when this landmark is an obstacle (anything but a ground patch).
    pub fn is_obstacle(&self) -> bool {
        !self.kind.is_ground()
    }

    /// `true` when an instruction can name this landmark: nothing else in its world looks
    /// the same (its name carries no `#` number).
    pub fn is_referable(&self) -> bool {
        !self.name.contains('#')
    }
}

/// An axis-aligned box `[N, E, U]` grown point by point: the extent of a scene, a path, a map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Extent {
    /// Lower corner.
    pub min: [f32; 3],
    /// Upper corner.
    pub max: [f32; 3],
}

impl Extent {
    /// The extent of the single point `p`.
    pub fn around(p: [f32; 3]) -> Extent {
        Extent { min: p, max: p }
    }

    /// Grow to hold `p`.
    pub fn include(&mut self, p: [f32; 3]) {
        for ((lo, hi), v) in self.min.iter_mut().zip(&mut self.max).zip(p) {
            *lo = lo.min(v);
            *hi = hi.max(v);
        }
    }

    /// Grow to hold `other`.
    pub fn union(&mut self, other: &Extent) {
        self.include(other.min);
        self.include(other.max);
    }
}

/// A named region that is not drawn itself, e.g. the forest its trees make up.
#[derive(Debug, Clone, PartialEq)]
pub struct Area {
    /// Human name, e.g. "forest".
    pub name: String,
    /// Lower corner `[N, E]` (m).
    pub min: [f32; 2],
    /// Upper corner `[N, E]` (m).
    pub max: [f32; 2],
}

impl Area {
    /// Centre `[N, E]`.
    pub fn centre(&self) -> [f32; 2] {
        [
            0.5 * (self.min[0] + self.max[0]),
            0.5 * (self.min[1] + self.max[1]),
        ]
    }
}

/// Where a ray met the world.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Distance from the ray origin (m, in units of the direction's length).
    pub distance: f32,
    /// Index into [`World::landmarks`], or [`GROUND`] for bare ground.
    pub landmark: usize,
    /// `true` when the top face (a roof, or the surface of a ground patch) was hit.
    pub roof: bool,
    /// Outward unit normal of the face hit (axis-aligned).
    pub normal: [f32; 3],
}

/// A scene of landmarks over a grass plane.
#[derive(Debug, Clone, PartialEq)]
pub struct World {
    /// Name of the world (e.g. "village").
    pub name: String,
    /// Its landmarks.
    pub landmarks: Vec<Landmark>,
    /// Named regions made of several landmarks (e.g. a forest); not drawn.
    pub areas: Vec<Area>,
}

pub(crate) fn lm(
    name: &str,
    kind: LandmarkKind,
    min: [f32; 3],
    max: [f32; 3],
    wall: [u8; 3],
    roof: [u8; 3],
) -> Landmark {
    Landmark {
        name: name.to_string(),
        kind,
        min,
        max,
        wall,
        roof,
    }
}

pub(crate) fn patch(
    name: &str,
    kind: LandmarkKind,
    n: [f32; 2],
    e: [f32; 2],
    colour: [u8; 3],
) -> Landmark {
    lm(
        name,
        kind,
        [n[0], e[0], 0.0],
        [n[1], e[1], GROUND_PATCH_MAX_U],
        colour,
        colour,
    )
}

pub(crate) fn tree(name: &str, n: f32, e: f32, height: f32) -> Landmark {
    lm(
        name,
        LandmarkKind::Tree,
        [n, e, 0.0],
        [n + 4.0, e + 4.0, height],
        palette::TREE_SIDE,
        palette::TREE_TOP,
    )
}

impl World {
    /// The landmark called `name`, if any.
    pub fn landmark_named(&self, name: &str) -> Option<&Landmark> {
        self.landmarks.iter().find(|l| l.name == name)
    }

    /// The box holding every landmark; `None` for a world without landmarks.
    pub fn extent(&self) -> Option<Extent> {
        let mut it = self.landmarks.iter();
        let first = it.next()?;
        let mut x = Extent {
            min: first.min,
            max: first.max,
        };
        for l in it {
            x.include(l.min);
            x.include(l.max);
        }
        Some(x)
    }

    /// The area called `name`, if any.
    pub fn area_named(&self, name: &str) -> Option<&Area> {
        self.areas.iter().find(|a| a.name == name)
    }

    /// Height (m) of the highest obstacle top over `(n, e)`; 0 when the ground is free.
    pub fn obstacle_top_at(&self, n: f32, e: f32) -> f32 {
        self.landmarks
            .iter()
            .filter(|l| l.is_obstacle() && l.covers(n, e))
            .fold(0.0, |top, l| top.max(l.max[2]))
    }

    /// `true` when a sphere of `radius` at `p` touches an obstacle, or `p` is below ground.
    /// The ground surface itself does not count as a collision.
    pub fn collides(&self, p: [f32; 3], radius: f32) -> bool {
        if p[2] < 0.0 {
            return true;
        }
        let r2 = radius * radius;
        self.landmarks.iter().filter(|l| l.is_obstacle()).any(|l| {
            let d2: f32 = (0..3)
                .map(|a| {
                    let d = (l.min[a] - p[a]).max(0.0).max(p[a] - l.max[a]);
                    d * d
                })
                .sum();
            d2 <= r2
        })
    }

    /// First hit of the ray `origin + t * dir`, `0 <= t <= max` (`dir` a unit vector).
    ///
    /// Boxes are tested with the slab method; a box that contains the origin is ignored (the
    /// ray starts inside it). Below every box lies the ground plane `U = 0` (landmark
    /// [`GROUND`]). Never allocates.
    pub fn raycast(&self, origin: [f32; 3], dir: [f32; 3], max: f32) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        let mut best_t = max;
        // ground plane
        if dir[2] < 0.0 && origin[2] >= 0.0 {
            let t = -origin[2] / dir[2];
            if t <= best_t {
                best_t = t;
                best = Some(Hit {
                    distance: t,
                    landmark: GROUND,
                    roof: true,
                    normal: [0.0, 0.0, 1.0],
                });
            }
        }
        for (i, l) in self.landmarks.iter().enumerate() {
            if let Some((t, axis, positive)) = slab(origin, dir, l.min, l.max, best_t)
                && t <= best_t
            {
                best_t = t;
                let mut normal = [0.0; 3];
                normal[axis] = if positive { 1.0 } else { -1.0 };
                best = Some(Hit {
                    distance: t,
                    landmark: i,
                    roof: axis == 2 && positive,
                    normal,
                });
            }
        }
        best
    }
}

/// Slab test: entry distance, entry axis and whether the entry face is the box's upper
/// face on that axis. `None` when the ray misses, starts inside, or enters beyond `max`.
#[inline]
fn slab(
    o: [f32; 3],
    d: [f32; 3],
    min: [f32; 3],
    max: [f32; 3],
    limit: f32,
) -> Option<(f32, usize, bool)> {
    let mut t_enter = f32::NEG_INFINITY;
    let mut t_exit = f32::INFINITY;
    let mut axis = 0;
    let mut positive = false;
    for a in 0..3 {
        if d[a].abs() < 1e-9 {
            if o[a] < min[a] || o[a] > max[a] {
                return None;
            }
            continue;
        }
        let inv = 1.0 / d[a];
        let (t0, t1, pos) = if inv >= 0.0 {
            ((min[a] - o[a]) * inv, (max[a] - o[a]) * inv, false)
        } else {
            ((max[a] - o[a]) * inv, (min[a] - o[a]) * inv, true)
        };
        if t0 > t_enter {
            t_enter = t0;
            axis = a;
            positive = pos;
        }
        t_exit = t_exit.min(t1);
        if t_enter > t_exit || t_exit < 0.0 || t_enter > limit {
            return None;
        }
    }
    if t_enter < 0.0 {
        // origin inside the box (or the box is degenerate around it)
        return None;
    }
    Some((t_enter, axis, positive))
}
