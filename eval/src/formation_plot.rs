//! The picture of a formation flight: one top-down panel per phase, every panel at the
//! same scale (a 5 m grid), each vehicle's track during that phase in its colour (a dot
//! where the phase began), the slots the phase ends on as hollow squares, and the phase's
//! caption with the slots' height at its end.
//!
//! Its input is [`FormationTracks`], the file a formation flight writes to its run folder
//! ([`FORMATION_TRACKS_FILE`]): `aeris formation plan --run DIR` writes the simulated flight
//! of the program it accepts there, the formation role of `aeris formation fly` the flight of
//! its vehicles (their telemetry) to the flight's run folder; `aeris plot formation --run
//! DIR` draws it.

use crate::plot::{PlotError, draw_text, text_width};
use image::{Rgb, RgbImage};
use imageproc::drawing::{draw_filled_rect_mut, draw_hollow_rect_mut, draw_line_segment_mut};
use imageproc::rect::Rect;

pub use aeris_formation::{FORMATION_TRACKS_FILE, FormationTracks, TrackSample};

/// Colours of the vehicles, in order (repeated past eight).
pub const VEHICLE_COLOURS: [[u8; 3]; 8] = [
    [220, 40, 40],
    [40, 110, 220],
    [30, 160, 70],
    [230, 140, 20],
    [140, 60, 190],
    [20, 170, 180],
    [200, 60, 150],
    [110, 110, 110],
];

const PAPER: [u8; 3] = [255, 255, 255];
const INK: [u8; 3] = [0, 0, 0];
const GRID: [u8; 3] = [225, 225, 225];
/// Pixels of one panel's plotting area, a side.
const PANEL: u32 = 240;
/// Space for a panel's caption.
const CAPTION: u32 = 30;
const GAP: u32 = 12;
const PANELS_PER_ROW: u32 = 4;

/// One panel per phase of `tracks` (north up, east right, a 5 m grid).
pub fn formation_chart(tracks: &FormationTracks) -> Result<RgbImage, PlotError> {
    let phases = tracks.phases.len().max(1) as u32;
    let columns = phases.min(PANELS_PER_ROW);
    let rows = phases.div_ceil(PANELS_PER_ROW);
    let width = columns * (PANEL + GAP) + GAP;
    let height = rows * (PANEL + CAPTION + GAP) + GAP;
    if tracks.points.is_empty() || tracks.vehicles == 0 {
        return Err(PlotError::Empty("a formation flight without track points"));
    }
    // one scale for every panel: the whole flight's positions and slots, 3 m of margin
    let (mut lo, mut hi) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
    for p in &tracks.points {
        for q in p.positions.iter().chain(&p.slots) {
            for k in 0..2 {
                lo[k] = lo[k].min(q[k]);
                hi[k] = hi[k].max(q[k]);
            }
        }
    }
    let span = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(1.0) + 6.0;
    let centre = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0];
    let scale = PANEL as f32 / span;
    let mut img = RgbImage::from_pixel(width, height, Rgb(PAPER));
    for (index, caption) in tracks.phases.iter().enumerate() {
        let phase = index + 1;
        let (column, row) = (index as u32 % PANELS_PER_ROW, index as u32 / PANELS_PER_ROW);
        let x0 = (GAP + column * (PANEL + GAP)) as f32;
        let y0 = (GAP + row * (PANEL + CAPTION + GAP) + CAPTION) as f32;
        // pixel of (n, e) in this panel: x grows east, y grows south
        let px = |n: f32, e: f32| {
            (
                x0 + PANEL as f32 / 2.0 + (e - centre[1]) * scale,
                y0 + PANEL as f32 / 2.0 - (n - centre[0]) * scale,
            )
        };
        // a 5 m grid
        let step = 5.0;
        let mut g = ((centre[1] - span / 2.0) / step).ceil() * step;
        while g <= centre[1] + span / 2.0 {
            let (x, _) = px(centre[0], g);
            draw_line_segment_mut(&mut img, (x, y0), (x, y0 + PANEL as f32), Rgb(GRID));
            g += step;
        }
        let mut g = ((centre[0] - span / 2.0) / step).ceil() * step;
        while g <= centre[0] + span / 2.0 {
            let (_, y) = px(g, centre[1]);
            draw_line_segment_mut(&mut img, (x0, y), (x0 + PANEL as f32, y), Rgb(GRID));
            g += step;
        }
        let frame = Rect::at(x0 as i32, y0 as i32).of_size(PANEL, PANEL);
        draw_hollow_rect_mut(&mut img, frame, Rgb(INK));
        let points: Vec<&TrackSample> = tracks.points.iter().filter(|p| p.phase == phase).collect();
        // "2 WEDGE 5M": the shape (or what the phase does) and the slots' height at its end
        let short = caption
            .strip_prefix("the change to a ")
            .or_else(|| caption.strip_prefix("the "))
            .unwrap_or(caption);
        let height = points.last().map_or(0.0, |p| {
            p.slots.iter().map(|s| s[2]).sum::<f32>() / p.slots.len().max(1) as f32
        });
        let label = format!("{phase} {} {height:.0}M", short.to_uppercase());
        let mut shown = label.as_str();
        while text_width(shown, 2) > PANEL && shown.len() > 1 {
            shown = &shown[..shown.len() - 1];
        }
        draw_text(
            &mut img,
            x0 as i32,
            y0 as i32 - CAPTION as i32 + 6,
            shown,
            2,
            INK,
        );
        for v in 0..tracks.vehicles {
            let colour = Rgb(VEHICLE_COLOURS[v % VEHICLE_COLOURS.len()]);
            for w in points.windows(2) {
                let (Some(a), Some(b)) = (w[0].positions.get(v), w[1].positions.get(v)) else {
                    continue;
                };
                let (a, b) = (px(a[0], a[1]), px(b[0], b[1]));
                for (dx, dy) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)] {
                    draw_line_segment_mut(
                        &mut img,
                        (a.0 + dx, a.1 + dy),
                        (b.0 + dx, b.1 + dy),
                        colour,
                    );
                }
            }
            if let Some(start) = points.first().and_then(|p| p.positions.get(v)) {
                let (x, y) = px(start[0], start[1]);
                draw_filled_rect_mut(
                    &mut img,
                    Rect::at(x as i32 - 2, y as i32 - 2).of_size(5, 5),
                    colour,
                );
            }
            if let Some(slot) = points.last().and_then(|p| p.slots.get(v)) {
                let (x, y) = px(slot[0], slot[1]);
                draw_hollow_rect_mut(
                    &mut img,
                    Rect::at(x as i32 - 5, y as i32 - 5).of_size(11, 11),
                    colour,
                );
            }
        }
    }
    Ok(img)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(t: f32, phase: usize, n: f32) -> TrackSample {
        TrackSample {
            t_s: t,
            phase,
            positions: vec![[n, 0.0, 5.0], [n, 4.0, 5.0]],
            slots: vec![[n, 0.0, 5.0], [n, 4.0, 5.0]],
        }
    }

    #[test]
    fn each_phase_gets_a_panel_with_each_vehicle_in_its_colour() {
        let tracks = FormationTracks {
            instruction: "two drones".into(),
            vehicles: 2,
            phases: vec!["take-off".into(), "the move".into()],
            source: "test".into(),
            points: vec![
                sample(0.0, 1, 0.0),
                sample(1.0, 2, 0.0),
                sample(2.0, 2, 10.0),
            ],
        };
        let img = formation_chart(&tracks).unwrap();
        assert_eq!(img.width(), 2 * (PANEL + GAP) + GAP);
        let has = |c: [u8; 3]| img.pixels().any(|p| p.0 == c);
        assert!(has(VEHICLE_COLOURS[0]) && has(VEHICLE_COLOURS[1]));
        assert!(!has(VEHICLE_COLOURS[2]));
        // the file round-trips
        let text = serde_json::to_string(&tracks).unwrap();
        let back: FormationTracks = serde_json::from_str(&text).unwrap();
        assert_eq!(back, tracks);
    }

    #[test]
    fn no_points_is_an_error_not_an_empty_picture() {
        let tracks = FormationTracks {
            instruction: String::new(),
            vehicles: 2,
            phases: vec!["take-off".into()],
            source: String::new(),
            points: Vec::new(),
        };
        assert!(formation_chart(&tracks).is_err());
    }
}
