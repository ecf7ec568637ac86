//! The built-in worlds by name: the fixed ones (`village`, `open`) and the generated
//! scenes (`open-<seed>`, `dense-<seed>`, [`crate::scene_gen`]).

use crate::world::{LandmarkKind, World, lm, palette, patch, tree};

impl World {
    /// Names of the fixed built-in worlds. Generated scenes are built in too, by name:
    /// `open-<seed>` and `dense-<seed>` (see [`crate::scene_gen`]).
    pub fn builtin_names() -> &'static [&'static str] {
        &["village", "open"]
    }

    /// What [`World::builtin`] accepts, for error messages.
    pub const NAMES_HELP: &'static str =
        "village, open, or a generated scene open-<seed> / dense-<seed> (seed 0..2^64)";

    /// A built-in world by name: a fixed one, or a generated scene (`dense-42`).
    pub fn builtin(name: &str) -> Option<World> {
        match name {
            "village" => Some(Self::village()),
            "open" => Some(Self::open()),
            _ => crate::scene_gen::SceneId::parse(name).map(crate::scene_gen::generate),
        }
    }

    /// Open airspace: a helipad on grass, nothing else.
    fn open() -> World {
        World {
            name: "open".into(),
            landmarks: vec![patch(
                "helipad",
                LandmarkKind::Helipad,
                [-6.0, 6.0],
                [-6.0, 6.0],
                palette::HELIPAD,
            )],
            areas: Vec::new(),
        }
    }

    /// The village the default mission flies in.
    ///
    /// The mission path `[0,0] -> [62,0] -> [62,64] -> [42,88]` keeps at least 6 m from
    /// every obstacle; `[42, 88]` (north of the LAKE VIEW sign) is a clear landing point.
    fn village() -> World {
        use LandmarkKind::*;
        let landmarks = vec![
            patch(
                "helipad",
                Helipad,
                [-6.0, 6.0],
                [-6.0, 6.0],
                palette::HELIPAD,
            ),
            patch("road north", Road, [6.0, 70.0], [-4.0, 4.0], palette::ROAD),
            patch(
                "road east",
                Road,
                [56.0, 68.0],
                [-4.0, 130.0],
                palette::ROAD,
            ),
            patch("lake", Water, [0.0, 30.0], [80.0, 125.0], palette::WATER),
            lm(
                "grey building west",
                Building,
                [20.0, -26.0, 0.0],
                [34.0, -10.0, 18.0],
                palette::GREY_WALL,
                palette::GREY_ROOF,
            ),
            lm(
                "grey building east",
                Building,
                [36.0, 12.0, 0.0],
                [50.0, 24.0, 10.0],
                palette::GREY_WALL,
                palette::GREY_ROOF,
            ),
            lm(
                "red-roofed building",
                Building,
                [72.0, 10.0, 0.0],
                [88.0, 26.0, 14.0],
                palette::BEIGE_WALL,
                palette::RED_ROOF,
            ),
            lm(
                "blue water tower",
                Tower,
                [80.0, 60.0, 0.0],
                [86.0, 66.0, 24.0],
                palette::TOWER_BLUE,
                palette::TOWER_TOP,
            ),
            lm(
                "yellow sign that says LAKE VIEW",
                Sign {
                    text: "LAKE VIEW".into(),
                },
                [34.0, 84.0, 2.0],
                [35.0, 92.0, 6.0],
                palette::SIGN_YELLOW,
                palette::SIGN_YELLOW,
            ),
            // west of the north road
            tree("tree 1", 4.0, -16.0, 7.0),
            tree("tree 2", 12.0, -14.0, 6.0),
            tree("tree 3", 40.0, -18.0, 8.0),
            tree("tree 4", 50.0, -13.0, 7.0),
            tree("tree 5", 72.0, -14.0, 6.0),
            // around the lake shore
            tree("tree 6", -6.0, 92.0, 7.0),
            tree("tree 7", 12.0, 127.0, 8.0),
            tree("tree 8", 32.0, 108.0, 6.0),
            tree("tree 9", 20.0, 72.0, 7.0),
        ];
        World {
            name: "village".into(),
            landmarks,
            areas: Vec::new(),
        }
    }
}
