//! `aeris scene video` writes an H.264 MP4 that an independent GStreamer decoder
//! (`filesrc ! qtdemux ! h264parse ! avdec_h264`) reads back as the expected number of frames
//! of the right size, each looking like the frame `aeris scene render` draws at the same pose.

use aeris_tests::*;
use gstreamer as gst;
use gstreamer::prelude::*;
use gstreamer_app as gst_app;
use std::process::Command;

/// Every frame of an MP4 as tight RGB rows, with its size.
fn decode(path: &std::path::Path) -> (u32, u32, Vec<Vec<u8>>) {
    gst::init().unwrap();
    let description = format!(
        "filesrc location={} ! qtdemux ! h264parse ! avdec_h264 ! videoconvert \
         ! video/x-raw,format=RGB ! appsink name=sink sync=false",
        path.display()
    );
    let pipeline = gst::parse::launch(&description)
        .unwrap()
        .downcast::<gst::Pipeline>()
        .unwrap();
    let sink = pipeline
        .by_name("sink")
        .unwrap()
        .downcast::<gst_app::AppSink>()
        .unwrap();
    pipeline.set_state(gst::State::Playing).unwrap();
    let (mut width, mut height) = (0, 0);
    let mut frames = Vec::new();
    // pull_sample blocks until a frame or the end of the stream (or an error)
    while let Ok(sample) = sink.pull_sample() {
        let s = sample.caps().unwrap().structure(0).unwrap();
        width = s.get::<i32>("width").unwrap() as u32;
        height = s.get::<i32>("height").unwrap() as u32;
        let map = sample.buffer().unwrap().map_readable().unwrap();
        let row = width as usize * 3;
        let stride = row.div_ceil(4) * 4;
        let mut frame = Vec::with_capacity(row * height as usize);
        for y in 0..height as usize {
            frame.extend_from_slice(&map[y * stride..y * stride + row]);
        }
        frames.push(frame);
    }
    let errors = pipeline
        .bus()
        .unwrap()
        .pop_filtered(&[gst::MessageType::Error]);
    assert!(errors.is_none(), "decoder error: {errors:?}");
    pipeline.set_state(gst::State::Null).unwrap();
    (width, height, frames)
}

/// `aeris scene render` at a pose, as RGB bytes.
fn render(dir: &std::path::Path, at: [f32; 3], yaw_deg: f32) -> Vec<u8> {
    let png = dir.join("render.png");
    let out = Command::new(aeris_bin())
        .args(["scene", "render", "village", "--at"])
        .arg(format!("{},{},{}", at[0], at[1], at[2]))
        .arg("--yaw")
        .arg(yaw_deg.to_string())
        .arg("--out")
        .arg(&png)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    image::open(&png).unwrap().to_rgb8().into_raw()
}

fn mean_rgb(bytes: &[u8]) -> [f64; 3] {
    let mut sum = [0f64; 3];
    for px in bytes.chunks_exact(3) {
        for c in 0..3 {
            sum[c] += f64::from(px[c]);
        }
    }
    sum.map(|s| s / (bytes.len() / 3) as f64)
}

/// Mean absolute difference per byte.
fn difference(a: &[u8], b: &[u8]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| f64::from(x.abs_diff(*y)))
        .sum::<f64>()
        / a.len() as f64
}

#[test]
fn an_mp4_of_a_path_decodes_to_its_rendered_frames() {
    let dir = TempDir::new("scene-video");
    let mp4 = dir.0.join("north.mp4");
    // 0,0,12 -> 40,0,12 at 5 m/s, 10 fps: 8 s = 80 intervals, 81 frames, looking north;
    let out = Command::new(aeris_bin())
        .args([
            "scene", "video", "village", "--path", "0,0,12", "--path", "40,0,12",
        ])
        .args(["--speed", "5", "--fps", "10", "--out"])
        .arg(&mp4)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("wrote 81 frames"), "{stdout}");

    let (w, h, frames) = decode(&mp4);
    assert_eq!((w, h), (320, 240));
    assert_eq!(frames.len(), 81, "decoded frames");

    let first = render(&dir.0, [0.0, 0.0, 12.0], 0.0);
    let last = render(&dir.0, [40.0, 0.0, 12.0], 0.0);
    assert!(
        difference(&first, &last) > 3.0,
        "the path's two ends look different"
    );
    for (decoded, rendered, other) in [(&frames[0], &first, &last), (&frames[80], &last, &first)] {
        let (m, r) = (mean_rgb(decoded), mean_rgb(rendered));
        for c in 0..3 {
            assert!(
                (m[c] - r[c]).abs() < 8.0,
                "mean colour {m:?} of the decoded frame, {r:?} rendered"
            );
        }
        // closer to the frame rendered at its own pose than to the other end's
        let own = difference(decoded, rendered);
        eprintln!(
            "decoded vs rendered: mean {m:?} / {r:?}, difference {own:.2} (other end {:.2})",
            difference(decoded, other)
        );
        assert!(
            own < difference(decoded, other),
            "decoded frame differs by {own} from its own pose's render"
        );
        assert!(own < 12.0, "decoded frame differs by {own} per byte");
    }
}
