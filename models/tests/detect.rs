//! Real detectors on real images through ONNX Runtime: the COCO detector finds the bus and
//! the people in Ultralytics' bus.jpg; the YOLOv8-layout model decodes on zidane.jpg.

use aeris_models::detect::{COCO_DETECTOR, YOLOV8_DETECTOR};
use aeris_models::{DetectedBox, Detector, DetectorLayout, ModelStore};

fn image(store: &ModelStore, name: &str) -> (Vec<u8>, usize, usize) {
    let path = store.verified(&format!("assets/{name}")).unwrap();
    let img = image::open(path).unwrap().to_rgb8();
    let (w, h) = img.dimensions();
    (img.into_raw(), w as usize, h as usize)
}

fn labels<'a>(d: &'a Detector, boxes: &[DetectedBox]) -> Vec<&'a str> {
    boxes
        .iter()
        .map(|b| d.names()[b.class_id].as_str())
        .collect()
}

#[test]
fn the_coco_detector_finds_the_bus_and_the_people() {
    let store = ModelStore::open(None).expect("model cache (run scripts/provision-models.sh)");
    let mut d =
        Detector::load(&store, COCO_DETECTOR, &aeris_models::SessionOptions::cpu(1)).unwrap();
    assert_eq!(d.layout(), DetectorLayout::Yolov5);
    assert_eq!(d.names().len(), 80);
    let (rgb, w, h) = image(&store, "bus.jpg");
    let mut boxes = Vec::new();
    d.detect(&rgb, w, h, &mut boxes).unwrap();
    let names = labels(&d, &boxes);
    let bus = boxes
        .iter()
        .find(|b| d.names()[b.class_id] == "bus")
        .unwrap_or_else(|| panic!("no bus in {names:?}"));
    // the bus spans most of the image width in its upper-middle part
    assert!(bus.bbox[2] > 0.6 * w as f32, "bus box {:?}", bus.bbox);
    let people = names.iter().filter(|n| **n == "person").count();
    assert!(people >= 3, "people found: {names:?}");
    for b in &boxes {
        assert!(b.bbox[0] >= 0.0 && b.bbox[1] >= 0.0);
        assert!(
            b.bbox[0] + b.bbox[2] <= w as f32 + 0.01 && b.bbox[1] + b.bbox[3] <= h as f32 + 0.01
        );
    }
}

#[test]
fn the_yolov8_layout_decodes_on_a_real_model() {
    let store = ModelStore::open(None).expect("model cache (run scripts/provision-models.sh)");
    let mut d = Detector::load(
        &store,
        YOLOV8_DETECTOR,
        &aeris_models::SessionOptions::cpu(1),
    )
    .unwrap();
    assert_eq!(d.layout(), DetectorLayout::Yolov8);
    assert_eq!(d.input_side_px(), 320);
    let (rgb, w, h) = image(&store, "zidane.jpg");
    let mut boxes = Vec::new();
    d.detect(&rgb, w, h, &mut boxes).unwrap();
    let names = labels(&d, &boxes);
    assert!(
        names.iter().filter(|n| **n == "FACE_MALE").count() >= 1,
        "{names:?}"
    );
    // a wrong-sized buffer is an error, not a panic
    assert!(d.detect(&rgb[..10], w, h, &mut boxes).is_err());
}
