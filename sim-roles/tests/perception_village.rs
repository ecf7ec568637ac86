//! Geometric perception on rendered frames of the village.

use aeris_schemas::{FixedText, FrameFormat, FrameHeader, OCCUPANCY_UNKNOWN, PerceptionState};
use aeris_sim::render::{
    CAMERA_MOUNT_HEIGHT_M, FACE_SHADES, Renderer, SKY_HORIZON, SKY_ZENITH, shaded,
};
use aeris_sim::world::{World, palette};
use aeris_sim_roles::perception::{InstructionWords, LABELS, Segmenter, perceive, push_u32};

const W: u32 = 320;
const H: u32 = 240;
const HFOV: f32 = std::f32::consts::FRAC_PI_2;

fn subgoals() -> InstructionWords {
    InstructionWords::new([
        "take off from the helipad",
        "fly north along the road",
        "turn right at the red-roofed building and follow the road east",
        "land next to the yellow sign that says LAKE VIEW",
    ])
}

/// Render the village from `vehicle` (vehicle position; the camera sits on its mount) and
/// run perception on the frame pair.
fn perceive_at(vehicle: [f32; 3], yaw: f32) -> PerceptionState {
    let world = World::builtin("village").unwrap();
    let r = Renderer::new(W, H, HFOV).unwrap();
    let mut rgb = vec![0; r.rgb_len()];
    let mut depth = vec![0; r.depth_len()];
    let cam = [vehicle[0], vehicle[1], vehicle[2] + CAMERA_MOUNT_HEIGHT_M];
    r.render(&world, cam, yaw, &mut rgb, &mut depth).unwrap();
    let header = FrameHeader {
        seq: 42,
        capture_ns: 1234,
        width: W,
        height: H,
        camera_position: cam,
        camera_yaw: yaw,
        hfov: HFOV,
        format: FrameFormat::Rgb8 as u8,
        reserved: [0; 3],
    };
    let mut state = PerceptionState::default();
    perceive(&rgb, &depth, &header, &subgoals(), &mut state).unwrap();
    state
}

fn detection<'a>(s: &'a PerceptionState, label: &str) -> Option<&'a aeris_schemas::Detection> {
    s.detections()
        .iter()
        .find(|d| d.label.as_str() == Some(label))
}

fn dist(a: [f32; 3], b: [f32; 3]) -> f32 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

#[test]
fn sees_the_red_roof_with_its_range_and_height() {
    let vehicle = [40.0, 18.0, 20.0];
    let s = perceive_at(vehicle, 0.0);
    assert_eq!(s.validate(), Ok(()));
    assert_eq!((s.frame_seq, s.capture_ns), (42, 1234));
    assert_eq!(s.position, vehicle);
    assert_eq!(s.yaw, 0.0);

    let roof = detection(&s, "red roof").expect("red roof detected");
    // seen from 6 m above the roof, most red pixels are the eaves on the near wall
    let cam = [40.0, 18.0, 20.0 + CAMERA_MOUNT_HEIGHT_M];
    let true_range = dist(cam, [72.0, 18.0, 14.0]); // nearest point of the building
    assert!(
        (roof.range_m - true_range).abs() < 3.0,
        "red roof range {} vs {true_range}",
        roof.range_m
    );
    assert!(roof.score > 0.5, "{roof:?}");
    // the roof is in the middle of the image, horizontally
    let cx = roof.bbox[0] + roof.bbox[2] / 2.0;
    assert!((cx - 0.5).abs() < 0.1, "{:?}", roof.bbox);
    assert!(detection(&s, "road").is_some());
    // detections come best first
    let scores: Vec<f32> = s.detections().iter().map(|d| d.score).collect();
    assert!(scores.windows(2).all(|w| w[0] >= w[1]), "{scores:?}");

    // occupancy: the building's cells read ~14 m, the road east 0, behind us unknown
    let g = &s.occupancy;
    assert!(g.is_present());
    assert_eq!(g.origin, [40.0, 18.0]);
    for p in [[80.0, 18.0], [74.0, 12.0], [86.0, 24.0], [72.5, 18.0]] {
        let h = g.height_at(p).expect("building cell observed");
        assert!((h - 14.0).abs() <= 1.0, "cell {p:?} = {h}");
    }
    for p in [[62.0, 18.0], [58.0, 10.0], [66.0, 26.0]] {
        assert_eq!(g.height_at(p), Some(0.0), "road cell {p:?}");
    }
    assert_eq!(g.height_at([30.0, 18.0]), None, "behind the camera");
    assert_eq!(g.cells[g.cell_of([30.0, 18.0]).unwrap()], OCCUPANCY_UNKNOWN);

    let summary = s.summary.as_str().unwrap();
    println!("summary: {summary}");
    assert!(summary.contains("red roof ahead"), "{summary}");
    assert!(summary.contains(" m"), "{summary}");

    let cue = s
        .cues()
        .iter()
        .find(|c| c.text.as_str() == Some("red roof"))
        .expect("red roof is a cue of `red-roofed building`");
    assert!((cue.score - roof.score).abs() < 1e-6, "full overlap");
    assert!(
        s.cues()
            .iter()
            .all(|c| c.text.as_str() != Some("blue water tower"))
    );
}

#[test]
fn from_above_the_red_roof_range_is_the_roof_centre() {
    let s = perceive_at([50.0, 18.0, 35.0], 0.0);
    assert_eq!(s.validate(), Ok(()));
    let roof = detection(&s, "red roof").expect("red roof detected");
    let cam = [50.0, 18.0, 35.0 + CAMERA_MOUNT_HEIGHT_M];
    // nearer roof pixels outnumber farther ones (perspective): the median sits a little
    // short of the centre, well inside the roof's near and far edges
    let true_range = dist(cam, [80.0, 18.0, 14.0]);
    let (near, far) = (dist(cam, [72.0, 18.0, 14.0]), dist(cam, [88.0, 18.0, 14.0]));
    assert!(roof.range_m > near && roof.range_m < far, "{roof:?}");
    assert!(
        (roof.range_m - true_range).abs() < 4.0,
        "red roof range {} vs {true_range}",
        roof.range_m
    );
    assert_eq!(
        s.detections()[0].label.as_str(),
        Some("red roof"),
        "{:?}",
        s.summary
    );
    for p in [[74.0, 12.0], [80.0, 18.0], [86.0, 24.0]] {
        assert_eq!(s.occupancy.height_at(p), Some(14.0), "{p:?}");
    }
}

#[test]
fn at_cruise_altitude_the_eaves_show_the_red_roof() {
    // mission altitude (12 m) is below the roof (14 m): the red band under the roof edge
    let s = perceive_at([50.0, 18.0, 12.0], 0.0);
    assert_eq!(s.validate(), Ok(()));
    let roof = detection(&s, "red roof").expect("red roof detected");
    let walls = detection(&s, "beige building").expect("beige walls detected");
    assert!(walls.score > roof.score);
    assert!((walls.range_m - 23.0).abs() < 3.0, "{walls:?}");
    let h = s.occupancy.height_at([72.5, 18.0]).unwrap();
    assert!((h - 14.0).abs() <= 1.0, "{h}");
}

#[test]
fn sees_the_yellow_sign_and_the_lake() {
    let s = perceive_at([48.0, 88.0, 6.0], std::f32::consts::PI);
    assert_eq!(s.validate(), Ok(()));
    let sign = detection(&s, "yellow sign").expect("sign detected");
    assert!((sign.range_m - 13.5).abs() < 2.0, "{sign:?}");
    assert!(detection(&s, "lake").is_some());
    let h = s
        .occupancy
        .height_at([34.5, 88.0])
        .expect("sign cell observed");
    assert!((h - 6.0).abs() <= 1.0, "{h}");
    let summary = s.summary.as_str().unwrap();
    assert!(summary.contains("yellow sign ahead"), "{summary}");
    let cue = s
        .cues()
        .iter()
        .find(|c| c.text.as_str() == Some("yellow sign"))
        .expect("sign cue");
    assert!(cue.score > 0.0);
}

#[test]
fn an_empty_view_recognises_nothing() {
    // high above open grass far from the village, looking away from it
    let s = perceive_at([-300.0, -300.0, 30.0], std::f32::consts::PI);
    assert_eq!(s.validate(), Ok(()));
    assert_eq!(s.detection_count, 0);
    assert_eq!(s.cue_count, 0);
    assert_eq!(s.summary.as_str(), Some("nothing recognised"));
    assert_eq!(s.occupancy.height_at([-330.0, -300.0]), Some(0.0));
}

#[test]
fn every_rendered_palette_colour_maps_to_its_class() {
    let seg = Segmenter::new();
    let cases: [(&str, [u8; 3], bool); 15] = [
        ("helipad", palette::HELIPAD, true),
        ("road", palette::ROAD, true),
        ("building", palette::GREY_WALL, false),
        ("building", palette::GREY_ROOF, false),
        ("red roof", palette::RED_ROOF, false),
        ("beige building", palette::BEIGE_WALL, false),
        ("blue water tower", palette::TOWER_BLUE, false),
        ("blue water tower", palette::TOWER_TOP, false),
        ("lake", palette::WATER, true),
        ("yellow sign", palette::SIGN_YELLOW, false),
        ("tree", palette::TREE_SIDE, false),
        ("tree", palette::TREE_TOP, false),
        ("blue roof", palette::BLUE_ROOF, false),
        ("green roof", palette::GREEN_ROOF, false),
        ("bridge", palette::BRIDGE, false),
    ];
    for (label, colour, ground) in cases {
        let shades: &[f32] = if ground {
            &FACE_SHADES[..1]
        } else {
            &FACE_SHADES
        };
        for s in shades {
            let c = shaded(colour, *s);
            assert_eq!(
                seg.classify(c).map(|i| LABELS[i]),
                Some(label),
                "{colour:?} x {s} = {c:?}"
            );
        }
    }
    for s in FACE_SHADES {
        assert_eq!(seg.classify(shaded(palette::SIGN_TEXT, s)), None);
    }
    assert_eq!(seg.classify(palette::GRASS), None);
    assert_eq!(seg.classify(SKY_HORIZON), None);
    assert_eq!(seg.classify(SKY_ZENITH), None);
}

#[test]
fn malformed_frames_are_rejected() {
    let header = FrameHeader {
        width: 4,
        height: 2,
        ..FrameHeader::default()
    };
    let mut s = PerceptionState::default();
    let w = subgoals();
    assert!(perceive(&[0; 24], &[0; 16], &header, &w, &mut s).is_ok());
    assert!(perceive(&[0; 23], &[0; 16], &header, &w, &mut s).is_err());
    assert!(perceive(&[0; 24], &[0; 15], &header, &w, &mut s).is_err());
    let depth_header = FrameHeader {
        format: FrameFormat::DepthU16Mm as u8,
        ..header
    };
    assert!(perceive(&[0; 16], &[0; 16], &depth_header, &w, &mut s).is_err());
    let bad = FrameHeader {
        hfov: f32::NAN,
        ..header
    };
    assert!(perceive(&[0; 24], &[0; 16], &bad, &w, &mut s).is_err());
}

#[test]
fn instruction_words_overlap_by_word_forms() {
    let w = subgoals();
    assert_eq!(w.len(), 4);
    assert_eq!(w.overlap("red roof"), 1.0);
    assert_eq!(w.overlap("yellow sign"), 1.0);
    assert_eq!(w.overlap("blue water tower"), 0.0);
    assert_eq!(w.overlap("beige building"), 0.5);
    let t = InstructionWords::new(["fly past the towers"]);
    assert!((t.overlap("blue water tower") - 1.0 / 3.0).abs() < 1e-6);
    let r = InstructionWords::new(["reduce speed"]);
    assert_eq!(r.overlap("red roof"), 0.0);
    assert!(InstructionWords::default().is_empty());
}

#[test]
fn numbers_format_without_allocation() {
    let mut t = FixedText::<16>::new();
    push_u32(&mut t, 0);
    t.push_str(" ");
    push_u32(&mut t, 4_294_967_295);
    assert_eq!(t.as_str(), Some("0 4294967295"));
}
