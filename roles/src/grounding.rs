//! Grounding instruction steps in S_t: which detection a step's landmark phrase names, and
//! where that landmark is in the world.
//!
//! A VLN instruction names places ("fly over the bridge", "land next to the yellow sign
//! that says HOTEL"), not coordinates. [`LandmarkPhrase::parse`] reads the relation and
//! the landmark's description from a step's text once, at mission start;
//! [`LandmarkPhrase::best_match`] then picks, in every new S_t, the detection whose label
//! names that description, and [`sight`] turns its box and range into a bearing and a
//! point on the ground plane from the pose at capture.
//!
//! Matching is by words, so it works with any detector's label set: every word of the
//! label must occur in the description (after light stemming, "roofed" ~ "roof", and a few
//! synonyms, "forest" ~ "tree"), and every colour the description names must be in the
//! label ("red-roofed building" is not any "building"). The sign's text is kept but not
//! used to choose between several signs: S_t carries read texts without positions.
//!
//! Everything here is allocation-free: the phrase lives in fixed-size text.

use aeris_geometry::CameraModel;
use aeris_schemas::state::CUE_MAX;
use aeris_schemas::{ActionMode, Detection, FixedText, PerceptionState, StepReading};

pub use aeris_schemas::Relation;

/// Words that name colours: a description's colours must all be in a matching label.
const COLOURS: [&str; 10] = [
    "red", "blue", "green", "yellow", "grey", "gray", "beige", "white", "black", "orange",
];

/// Description word -> label word it also stands for.
const SYNONYMS: [(&str, &str); 5] = [
    ("forest", "tree"),
    ("woods", "tree"),
    ("river", "lake"),
    ("water", "lake"),
    ("pond", "lake"),
];

/// Words of `s`: maximal runs of ASCII letters and digits.
fn words(s: &str) -> impl Iterator<Item = &str> {
    s.split(|c: char| !c.is_ascii_alphanumeric())
        .filter(|w| !w.is_empty())
}

/// `w` without a plural or participle ending ("roofed" -> "roof", "trees" -> "tree").
fn stem(w: &str) -> &str {
    for suffix in ["ed", "s"] {
        if w.len() > suffix.len() + 2
            && w.is_char_boundary(w.len() - suffix.len())
            && w[w.len() - suffix.len()..].eq_ignore_ascii_case(suffix)
        {
            return &w[..w.len() - suffix.len()];
        }
    }
    w
}

fn same_word(a: &str, b: &str) -> bool {
    stem(a).eq_ignore_ascii_case(stem(b))
}

/// The landmark a step names, as read from its text.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LandmarkPhrase {
    /// The relation of the step to the landmark.
    pub relation: Relation,
    /// The description ("red-roofed building", "yellow sign").
    pub description: FixedText<CUE_MAX>,
    /// The text the landmark carries, when the step quotes one ("LAKE VIEW"), else empty.
    pub sign_text: FixedText<CUE_MAX>,
}

impl LandmarkPhrase {
    /// The landmark of a step text such as "turn left and fly to the red-roofed building";
    /// `None` when the text names no relation this grounding knows.
    pub fn parse(text: &str) -> Option<Self> {
        // the relation closest to the end wins ("fly to the lake and land next to ...")
        // the last whole-word occurrence ("over" in "hover" is none)
        let lower_find = |needle: &str| {
            let b = text.as_bytes();
            (0..b.len().saturating_sub(needle.len() - 1))
                .rev()
                .find(|&i| {
                    b[i..i + needle.len()].eq_ignore_ascii_case(needle.as_bytes())
                        && (i == 0 || !b[i - 1].is_ascii_alphanumeric())
                })
        };
        let mut best: Option<(usize, usize, Relation)> = None;
        for (needle, relation) in [
            ("next to ", Relation::NextTo),
            ("fly over ", Relation::Over),
            ("over ", Relation::Over),
            ("fly to ", Relation::To),
            ("towards ", Relation::To),
            ("to ", Relation::To),
        ] {
            if let Some(at) = lower_find(needle)
                && best.is_none_or(|(b, _, _)| at > b)
                // "to " inside "next to " is the same relation, found first
                && !(needle == "to " && best.is_some_and(|(b, len, _)| at < b + len))
            {
                best = Some((at, needle.len(), relation));
            }
        }
        let (at, len, relation) = best?;
        let mut rest = text[at + len..].trim();
        for article in ["the ", "a ", "an "] {
            if rest.len() > article.len() && rest[..article.len()].eq_ignore_ascii_case(article) {
                rest = rest[article.len()..].trim_start();
            }
        }
        let rest = rest.trim_end_matches(['.', ',', ';', ' ']);
        let (description, sign) = match find_ci(rest, " that says ") {
            Some(i) => (&rest[..i], rest[i + " that says ".len()..].trim()),
            None => (rest, ""),
        };
        let description = description.trim();
        // "to 20 metres" is a quantity, not a place
        if description.is_empty() || description.starts_with(|c: char| c.is_ascii_digit()) {
            return None;
        }
        Some(Self {
            relation,
            description: FixedText::from_str_truncated(description),
            sign_text: FixedText::from_str_truncated(sign),
        })
    }

    /// The landmark a model read in a step ([`StepReading`]) whose action is `action`: its
    /// landmark label as the description, its sign text, its relation (`To` when it read a
    /// landmark and no relation); `None` when it read no landmark. A quoted sign is read
    /// from in front of it, so a step to one is never flown `Over` it: it goes `To` it, or
    /// lands `NextTo` it.
    pub fn from_reading(reading: &StepReading, action: ActionMode) -> Option<Self> {
        let landmark = reading.landmark.as_deref()?.trim();
        let sign = reading.sign.as_deref().unwrap_or("").trim();
        let relation = match (reading.relation.unwrap_or(Relation::To), action) {
            (Relation::Over, ActionMode::Land) if !sign.is_empty() => Relation::NextTo,
            (Relation::Over, _) if !sign.is_empty() => Relation::To,
            (r, _) => r,
        };
        (!landmark.is_empty()).then(|| Self {
            relation,
            description: FixedText::from_str_truncated(landmark),
            sign_text: FixedText::from_str_truncated(sign),
        })
    }

    /// How well `label` names this landmark: the number of label words, when every one of
    /// them is in the description and the label has every colour the description names;
    /// `None` otherwise.
    pub fn match_label(&self, label: &str) -> Option<u32> {
        let description = self.description.as_str_lossy();
        let in_description = |lw: &str| {
            words(description).any(|dw| {
                same_word(dw, lw)
                    || SYNONYMS
                        .iter()
                        .any(|(d, l)| same_word(dw, d) && same_word(lw, l))
            })
        };
        let mut n = 0;
        for lw in words(label) {
            if !in_description(lw) {
                return None;
            }
            n += 1;
        }
        let colours_covered = words(description)
            .filter(|dw| COLOURS.iter().any(|c| same_word(dw, c)))
            .all(|dw| words(label).any(|lw| same_word(lw, dw)));
        (n > 0 && colours_covered).then_some(n)
    }

    /// The detection of `state` that best names this landmark (most label words, then
    /// highest score).
    pub fn best_match<'a>(&self, state: &'a PerceptionState) -> Option<&'a Detection> {
        self.best_match_where(state, |_| true)
    }

    /// [`LandmarkPhrase::best_match`] among the detections `keep` accepts.
    pub fn best_match_where<'a>(
        &self,
        state: &'a PerceptionState,
        mut keep: impl FnMut(&Detection) -> bool,
    ) -> Option<&'a Detection> {
        let n = (state.detection_count as usize).min(state.detections.len());
        state.detections[..n]
            .iter()
            .filter_map(|d| Some((self.match_label(d.label.as_str_lossy())?, d)))
            .filter(|(_, d)| keep(d))
            .max_by(|(a, da), (b, db)| a.cmp(b).then(da.score.total_cmp(&db.score)))
            .map(|(_, d)| d)
    }

    /// Whether this landmark is certainly not `other`'s: both quote a sign text and the
    /// texts differ ("the sign that says HOTEL" is not the one that says MUSEUM).
    pub fn differs_from(&self, other: &LandmarkPhrase) -> bool {
        let (a, b) = (
            self.sign_text.as_str_lossy(),
            other.sign_text.as_str_lossy(),
        );
        !a.is_empty() && !b.is_empty() && !a.eq_ignore_ascii_case(b)
    }
}

/// What the text read on signs says about the sign a step quotes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SignReading {
    /// The quoted text was read (at least half its words, each within one letter).
    Quoted,
    /// Something else was read: the sign in view is another one.
    Other,
    /// Nothing was read.
    Nothing,
}

/// Compare the text `read` on signs with the `quoted` text of a step. Words of fewer than
/// three characters do not count; a word matches a read word within one edit (PP-OCR
/// reads the renderer's 5x7 "V" as "U" at times).
pub fn sign_reading(read: &str, quoted: &str) -> SignReading {
    if words(read).next().is_none() {
        return SignReading::Nothing;
    }
    let (mut wanted, mut seen) = (0, 0);
    for q in words(quoted).filter(|w| w.len() >= 3) {
        wanted += 1;
        if words(read).any(|r| within_one_edit(r, q)) {
            seen += 1;
        }
    }
    if wanted > 0 && 2 * seen >= wanted {
        SignReading::Quoted
    } else {
        SignReading::Other
    }
}

/// Case-insensitive Levenshtein distance of `a` and `b` is at most 1.
fn within_one_edit(a: &str, b: &str) -> bool {
    let (a, b) = (a.as_bytes(), b.as_bytes());
    let (long, short) = if a.len() >= b.len() { (a, b) } else { (b, a) };
    if long.len() - short.len() > 1 {
        return false;
    }
    let eq = |x: u8, y: u8| x.eq_ignore_ascii_case(&y);
    let prefix = long
        .iter()
        .zip(short)
        .take_while(|(x, y)| eq(**x, **y))
        .count();
    if prefix == short.len() {
        return true;
    }
    let rest = |l: &[u8], s: &[u8]| l.len() == s.len() && l.iter().zip(s).all(|(x, y)| eq(*x, *y));
    if long.len() == short.len() {
        // one substitution
        rest(&long[prefix + 1..], &short[prefix + 1..])
    } else {
        // one insertion into the shorter
        rest(&long[prefix + 1..], &short[prefix..])
    }
}

/// Case-insensitive byte offset of `needle` in `hay`.
fn find_ci(hay: &str, needle: &str) -> Option<usize> {
    hay.as_bytes()
        .windows(needle.len())
        .position(|w| w.eq_ignore_ascii_case(needle.as_bytes()))
}

/// Where a detection is, seen from the pose at capture.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sighting {
    /// World bearing of the box centre (rad, 0 = north, clockwise).
    pub bearing: f32,
    /// Ground point `[N, E]` of the detection at its measured range; `None` when the range
    /// is unknown (beyond the depth sensor).
    pub point: Option<[f32; 2]>,
}

/// Bearing and ground point of `d` seen by `camera` from `position` facing `yaw` (S_t's
/// pose at capture). The range is the detection's median distance along the rays; its
/// horizontal part puts the point on the ground plane.
pub fn sight(d: &Detection, position: [f32; 3], yaw: f32, camera: &CameraModel) -> Sighting {
    let [x, y, w, h] = d.bbox;
    let ray = camera.ray_at(
        (x + 0.5 * w) * camera.width as f32,
        (y + 0.5 * h) * camera.height as f32,
    );
    let horizontal = ray[0].hypot(ray[1]);
    let norm = (horizontal * horizontal + ray[2] * ray[2]).sqrt();
    let bearing = yaw + ray[1].atan2(ray[0]);
    let point = (d.range_m > 0.0 && d.range_m.is_finite() && norm > 0.0).then(|| {
        let r = d.range_m * horizontal / norm;
        [
            position[0] + r * bearing.cos(),
            position[1] + r * bearing.sin(),
        ]
    });
    Sighting { bearing, point }
}

/// Heading change (rad, positive right) that a step's text asks for before it flies:
/// "turn left" -pi/2, "turn right" +pi/2, "turn around" pi, otherwise 0.
pub fn turn_of(text: &str) -> f32 {
    if find_ci(text, "turn left").is_some() {
        -core::f32::consts::FRAC_PI_2
    } else if find_ci(text, "turn right").is_some() {
        core::f32::consts::FRAC_PI_2
    } else if find_ci(text, "turn around").is_some() || find_ci(text, "turn back").is_some() {
        core::f32::consts::PI
    } else {
        0.0
    }
}

/// The height a take-off step names ("take off to 20 metres", "climb to 15 m").
pub fn height_of(text: &str) -> Option<f32> {
    let mut last: Option<f32> = None;
    let mut ws = words(text).peekable();
    while let Some(w) = ws.next() {
        if let Ok(v) = w.parse::<f32>()
            && ws
                .peek()
                .is_some_and(|u| ["m", "metres", "meters", "metre", "meter"].contains(u))
        {
            last = Some(v);
        }
    }
    last.filter(|v| v.is_finite() && *v > 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn det(label: &str, score: f32, bbox: [f32; 4], range_m: f32) -> Detection {
        let mut d = Detection {
            score,
            bbox,
            range_m,
            ..Detection::default()
        };
        d.label.set(label);
        d
    }

    #[test]
    fn parses_the_relation_and_the_description() {
        let p = LandmarkPhrase::parse("turn left and fly to the red-roofed building").unwrap();
        assert_eq!(p.relation, Relation::To);
        assert_eq!(p.description.as_str_lossy(), "red-roofed building");
        let p = LandmarkPhrase::parse("fly over the bridge").unwrap();
        assert_eq!(
            (p.relation, p.description.as_str_lossy()),
            (Relation::Over, "bridge")
        );
        let p = LandmarkPhrase::parse("land next to the yellow sign that says LAKE VIEW").unwrap();
        assert_eq!(p.relation, Relation::NextTo);
        assert_eq!(p.description.as_str_lossy(), "yellow sign");
        assert_eq!(p.sign_text.as_str_lossy(), "LAKE VIEW");
        assert_eq!(LandmarkPhrase::parse("hover for a while"), None);
        assert_eq!(LandmarkPhrase::parse("take off to 20 metres"), None);
    }

    #[test]
    fn labels_match_by_words_colours_and_synonyms() {
        let red = LandmarkPhrase::parse("fly to the red-roofed building").unwrap();
        assert_eq!(red.match_label("red roof"), Some(2));
        assert_eq!(
            red.match_label("building"),
            None,
            "the colour is not optional"
        );
        assert_eq!(red.match_label("blue roof"), None);
        let tower = LandmarkPhrase::parse("fly to the blue water tower").unwrap();
        assert_eq!(tower.match_label("blue water tower"), Some(3));
        assert_eq!(tower.match_label("blue roof"), None);
        let forest = LandmarkPhrase::parse("fly over the forest").unwrap();
        assert_eq!(forest.match_label("tree"), Some(1));
        let sign =
            LandmarkPhrase::parse("land next to the yellow sign that says LAKE VIEW").unwrap();
        assert_eq!(sign.match_label("yellow sign"), Some(2));
        assert_eq!(
            sign.match_label("lake"),
            None,
            "the sign's text is not a landmark"
        );
    }

    #[test]
    fn the_most_specific_label_wins() {
        let p = LandmarkPhrase::parse("fly to the red-roofed building").unwrap();
        let mut s = PerceptionState::default();
        s.detections[0] = det("building", 0.9, [0.0; 4], 10.0);
        s.detections[1] = det("red roof", 0.2, [0.0; 4], 30.0);
        s.detections[2] = det("road", 0.8, [0.0; 4], 5.0);
        s.detection_count = 3;
        assert_eq!(p.best_match(&s).unwrap().label.as_str_lossy(), "red roof");
        s.detection_count = 1;
        assert_eq!(p.best_match(&s), None);
    }

    #[test]
    fn a_centred_detection_lies_ahead_at_its_horizontal_range() {
        let camera = CameraModel::with_pitch(320, 240, 90f32.to_radians(), 0.0).unwrap();
        // box centred on the image: straight ahead, level camera -> range is horizontal
        let d = det("lake", 1.0, [0.4, 0.4, 0.2, 0.2], 30.0);
        let s = sight(&d, [10.0, 5.0, 20.0], core::f32::consts::FRAC_PI_2, &camera);
        assert!((s.bearing - core::f32::consts::FRAC_PI_2).abs() < 1e-5);
        let p = s.point.unwrap();
        assert!(
            (p[0] - 10.0).abs() < 1e-3 && (p[1] - 35.0).abs() < 1e-3,
            "{p:?}"
        );
        // a box at the right edge is 45 degrees right of the heading
        let d = det("lake", 1.0, [0.9, 0.4, 0.2, 0.2], 0.0);
        let s = sight(&d, [0.0; 3], 0.0, &camera);
        assert!((s.bearing - 45f32.to_radians()).abs() < 1e-3);
        assert_eq!(s.point, None, "no range, no point");
    }

    #[test]
    fn sign_texts_are_read_with_one_letter_of_slack() {
        assert_eq!(sign_reading("LAKE UIEW", "LAKE VIEW"), SignReading::Quoted);
        assert_eq!(sign_reading("HOTEL", "hotel"), SignReading::Quoted);
        assert_eq!(sign_reading("CITY HAL", "CITY HALL"), SignReading::Quoted);
        assert_eq!(sign_reading("MUSEUM", "HOTEL"), SignReading::Other);
        assert_eq!(sign_reading("", "HOTEL"), SignReading::Nothing);
        assert!(within_one_edit("STATION", "STATON"));
        assert!(!within_one_edit("STATION", "NATION"));
    }

    #[test]
    fn turns_and_heights_from_the_text() {
        assert!(turn_of("turn left and fly to the lake") < 0.0);
        assert!(turn_of("turn right and fly over the bridge") > 0.0);
        assert_eq!(turn_of("fly to the lake"), 0.0);
        assert_eq!(
            height_of("take off from the helipad to 25 metres"),
            Some(25.0)
        );
        assert_eq!(height_of("take off"), None);
    }
}
