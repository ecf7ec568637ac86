//! A world-frame memory of the occupancy grids a flight has seen.
//!
//! The occupancy block of S_t is ego-centred and rebuilt from every frame: it shows only
//! what the camera sees now, never what lies under the vehicle. A landing decided from it
//! alone comes down onto a roof the camera saw on the approach and lost from view
//! overhead. [`HeightMap`] keeps, for every cell of the geofence, the highest obstacle top
//! ever observed there (the scenes are static, and the higher reading is the safe one), so
//! a touchdown point is checked against everything the flight has seen.
//!
//! [`HeightMap::next_to`] chooses where "land next to X" touches down: the landmark's
//! footprint is the connected block of obstacle cells at X's sighting, and the touchdown
//! is the point of clear, observed ground next to that footprint nearest to the vehicle
//! (the approach side, as a person would land).
//!
//! Storage is allocated once, in [`HeightMap::covering`]; every other call is
//! allocation-free and bounded by the map's fixed windows.

use aeris_schemas::{OCCUPANCY_SIDE, OCCUPANCY_UNKNOWN, OccupancyGrid};

/// Metres per cell: the occupancy grid's resolution.
pub const CELL_M: f32 = crate::depth_occupancy::OCCUPANCY_RESOLUTION_M;
/// Most cells per side (a 1 km square at 2 m); a larger geofence is covered around its
/// centre only.
pub const MAX_SIDE: usize = 500;
/// Cells at least this high (m) are obstacles: part of a landmark's footprint.
pub const OBSTACLE_TOP_M: f32 = 2.0;
/// A footprint starts at the obstacle cell nearest to the sighting within this (m).
pub const SEED_M: f32 = 10.0;
/// A footprint extends at most this far (m) from its seed cell in each axis: a building
/// of a dense block (up to 40 m) seen from its far corner, and not the next block.
pub const FOOTPRINT_M: f32 = 40.0;
/// A touchdown is "next to" a footprint when a footprint cell is within this (m).
pub const NEXT_TO_MAX_M: f32 = 12.0;

/// Side (cells) of the window the flood fill may visit.
const FILL_SIDE: usize = 2 * (FOOTPRINT_M / CELL_M) as usize + 1;

/// A landmark's footprint: the cells of the last [`HeightMap::footprint`] call, marked in
/// the map's scratch with `mark`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Footprint {
    mark: u32,
    /// Bounding box in cells, `[min row, min col, max row, max col]` inclusive.
    rows_cols: [usize; 4],
    /// Cells in the footprint; 0 when the landmark showed no obstacle cell (a flat one,
    /// or not yet seen in the map): then the footprint is the sighting's cell.
    pub cells: usize,
}

/// The heights the flight has observed, on a fixed world-frame grid.
#[derive(Debug, Clone)]
pub struct HeightMap {
    /// `[N, E]` of the south-west corner of cell (0, 0).
    corner: [f32; 2],
    side: usize,
    /// Highest obstacle top seen per cell (m), [`OCCUPANCY_UNKNOWN`] when never observed.
    cells: Vec<u8>,
    /// Footprint marks of the flood fill (`== mark` means in the current footprint).
    marks: Vec<u32>,
    mark: u32,
    /// The flood fill's work list, capacity of its whole window.
    stack: Vec<u32>,
}

impl HeightMap {
    /// A map of the square that covers `min`..`max` (`[N, E]`, the geofence), at most
    /// [`MAX_SIDE`] cells a side around its centre; nothing observed yet.
    pub fn covering(min: [f32; 2], max: [f32; 2]) -> Self {
        let span = (max[0] - min[0]).max(max[1] - min[1]);
        let side = if span.is_finite() && span > 0.0 {
            ((span / CELL_M).ceil() as usize + 1).clamp(1, MAX_SIDE)
        } else {
            1
        };
        let centre = [0.5 * (min[0] + max[0]), 0.5 * (min[1] + max[1])];
        let centre = if centre[0].is_finite() && centre[1].is_finite() {
            centre
        } else {
            [0.0; 2]
        };
        let half = 0.5 * side as f32 * CELL_M;
        Self {
            corner: [centre[0] - half, centre[1] - half],
            side,
            cells: vec![OCCUPANCY_UNKNOWN; side * side],
            marks: vec![0; side * side],
            mark: 0,
            stack: Vec::with_capacity(FILL_SIDE * FILL_SIDE),
        }
    }

    /// `(row, col)` of the cell holding `p`, if inside the map.
    fn cell(&self, p: [f32; 2]) -> Option<(usize, usize)> {
        let r = ((p[0] - self.corner[0]) / CELL_M).floor();
        let c = ((p[1] - self.corner[1]) / CELL_M).floor();
        (r >= 0.0 && c >= 0.0 && (r as usize) < self.side && (c as usize) < self.side)
            .then_some((r as usize, c as usize))
    }

    /// `[N, E]` of the centre of cell `(row, col)`.
    fn centre(&self, r: usize, c: usize) -> [f32; 2] {
        [
            self.corner[0] + (r as f32 + 0.5) * CELL_M,
            self.corner[1] + (c as f32 + 0.5) * CELL_M,
        ]
    }

    /// Take in every observed cell of `grid`: a cell keeps the highest top seen there.
    pub fn absorb(&mut self, grid: &OccupancyGrid) {
        if !grid.is_present() || !grid.resolution_m.is_finite() {
            return;
        }
        let half = (OCCUPANCY_SIDE / 2) as f32;
        for (i, &v) in grid.cells.iter().enumerate() {
            if v == OCCUPANCY_UNKNOWN {
                continue;
            }
            let (r, c) = (i / OCCUPANCY_SIDE, i % OCCUPANCY_SIDE);
            let p = [
                grid.origin[0] + (r as f32 - half + 0.5) * grid.resolution_m,
                grid.origin[1] + (c as f32 - half + 0.5) * grid.resolution_m,
            ];
            if let Some((mr, mc)) = self.cell(p) {
                let cell = &mut self.cells[mr * self.side + mc];
                if *cell == OCCUPANCY_UNKNOWN || v > *cell {
                    *cell = v;
                }
            }
        }
    }

    /// Highest obstacle top observed at `p` (m); `None` when never observed or outside.
    pub fn height_at(&self, p: [f32; 2]) -> Option<f32> {
        let (r, c) = self.cell(p)?;
        let v = self.cells[r * self.side + c];
        (v != OCCUPANCY_UNKNOWN).then_some(v as f32)
    }

    /// Whether every cell within `half_side` (m) of `p` was observed as free ground.
    pub fn is_clear(&self, p: [f32; 2], half_side: f32) -> bool {
        self.every_cell_within(p, half_side, |h| h.is_some_and(|h| h < 0.5))
    }

    /// Whether no cell within `half_side` (m) of `p` was observed holding an obstacle:
    /// unknown cells count as free, as the hub's gate counts them.
    pub fn no_obstacle_near(&self, p: [f32; 2], half_side: f32) -> bool {
        self.every_cell_within(p, half_side, |h| h.is_none_or(|h| h < 0.5))
    }

    /// Whether `ok` holds for the height ([`HeightMap::height_at`]) of every cell of the
    /// square of half side `half_side` (m) around `p`.
    fn every_cell_within(
        &self,
        p: [f32; 2],
        half_side: f32,
        ok: impl Fn(Option<f32>) -> bool,
    ) -> bool {
        let steps = (half_side / CELL_M).ceil() as i32;
        (-steps..=steps).all(|i| {
            (-steps..=steps)
                .all(|j| ok(self.height_at([p[0] + i as f32 * CELL_M, p[1] + j as f32 * CELL_M])))
        })
    }

    fn is_obstacle(&self, r: usize, c: usize) -> bool {
        let v = self.cells[r * self.side + c];
        v != OCCUPANCY_UNKNOWN && v as f32 >= OBSTACLE_TOP_M
    }

    /// The footprint of the landmark sighted at `p`: the 4-connected obstacle cells around
    /// the obstacle cell nearest to `p` (within [`SEED_M`]), at most [`FOOTPRINT_M`] from
    /// it in each axis. `None` when `p` is outside the map.
    pub fn footprint(&mut self, p: [f32; 2]) -> Option<Footprint> {
        let (pr, pc) = self.cell(p)?;
        self.mark = self.mark.wrapping_add(1);
        if self.mark == 0 {
            self.marks.fill(0);
            self.mark = 1;
        }
        let reach = (SEED_M / CELL_M).ceil() as usize;
        let mut seed: Option<(usize, usize, usize)> = None;
        for r in pr.saturating_sub(reach)..=(pr + reach).min(self.side - 1) {
            for c in pc.saturating_sub(reach)..=(pc + reach).min(self.side - 1) {
                let d2 = r.abs_diff(pr).pow(2) + c.abs_diff(pc).pow(2);
                if d2 <= reach * reach
                    && self.is_obstacle(r, c)
                    && seed.is_none_or(|(_, _, best)| d2 < best)
                {
                    seed = Some((r, c, d2));
                }
            }
        }
        let Some((sr, sc, _)) = seed else {
            self.marks[pr * self.side + pc] = self.mark;
            return Some(Footprint {
                mark: self.mark,
                rows_cols: [pr, pc, pr, pc],
                cells: 0,
            });
        };
        let lim = FILL_SIDE / 2;
        let (lo_r, hi_r) = (sr.saturating_sub(lim), (sr + lim).min(self.side - 1));
        let (lo_c, hi_c) = (sc.saturating_sub(lim), (sc + lim).min(self.side - 1));
        let mut bbox = [sr, sc, sr, sc];
        let mut count = 0;
        self.stack.clear();
        self.marks[sr * self.side + sc] = self.mark;
        self.stack.push((sr * self.side + sc) as u32);
        while let Some(i) = self.stack.pop() {
            let (r, c) = (i as usize / self.side, i as usize % self.side);
            count += 1;
            bbox = [
                bbox[0].min(r),
                bbox[1].min(c),
                bbox[2].max(r),
                bbox[3].max(c),
            ];
            let neighbours = [
                (r > lo_r).then(|| (r - 1, c)),
                (r < hi_r).then(|| (r + 1, c)),
                (c > lo_c).then(|| (r, c - 1)),
                (c < hi_c).then(|| (r, c + 1)),
            ];
            for (nr, nc) in neighbours.into_iter().flatten() {
                let j = nr * self.side + nc;
                // every cell is marked once, so the stack never outgrows the window
                if self.marks[j] != self.mark && self.is_obstacle(nr, nc) {
                    self.marks[j] = self.mark;
                    self.stack.push(j as u32);
                }
            }
        }
        Some(Footprint {
            mark: self.mark,
            rows_cols: bbox,
            cells: count,
        })
    }

    /// A board (a sign) sighted at `p`: the centre of its footprint and the unit normal of
    /// its faces, `[N, E]`, when the footprint is at least twice as long one way as the
    /// other and at least 3 cells long. A board is read from in front of a face; seen
    /// edge-on it shows no text.
    pub fn board(&mut self, p: [f32; 2]) -> Option<([f32; 2], [f32; 2])> {
        let f = self.footprint(p)?;
        if f.cells == 0 {
            return None;
        }
        let [r0, c0, r1, c1] = f.rows_cols;
        let (rows, cols) = (r1 - r0 + 1, c1 - c0 + 1);
        let a = self.centre(r0, c0);
        let b = self.centre(r1, c1);
        let centre = [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])];
        if cols >= 3 && cols >= 2 * rows {
            Some((centre, [1.0, 0.0]))
        } else if rows >= 3 && rows >= 2 * cols {
            Some((centre, [0.0, 1.0]))
        } else {
            None
        }
    }

    /// Whether a cell of `footprint` lies within [`NEXT_TO_MAX_M`] of `p`.
    fn beside(&self, footprint: &Footprint, p: [f32; 2]) -> bool {
        let Some((pr, pc)) = self.cell(p) else {
            return false;
        };
        let reach = (NEXT_TO_MAX_M / CELL_M).floor() as usize;
        let [r0, c0, r1, c1] = footprint.rows_cols;
        let (lo_r, hi_r) = (pr.saturating_sub(reach).max(r0), (pr + reach).min(r1));
        let (lo_c, hi_c) = (pc.saturating_sub(reach).max(c0), (pc + reach).min(c1));
        (lo_r..=hi_r).any(|r| {
            (lo_c..=hi_c).any(|c| {
                self.marks[r * self.side + c] == footprint.mark
                    && r.abs_diff(pr).pow(2) + c.abs_diff(pc).pow(2) <= reach * reach
            })
        })
    }

    /// Where to touch down next to the landmark sighted at `p`, coming from `from`: the
    /// centre of a cell beside its footprint (within [`NEXT_TO_MAX_M`]) whose surroundings
    /// within `clear_m` are observed free ground, nearest to `from`. `previous`, the
    /// touchdown chosen before, is kept while it still qualifies and is no more than
    /// `keep_m` farther from `from` than the best point, so the touchdown does not wander
    /// as the sighting and the map grow. `None` when no observed ground qualifies yet.
    pub fn next_to(
        &mut self,
        p: [f32; 2],
        from: [f32; 2],
        clear_m: f32,
        previous: Option<[f32; 2]>,
        keep_m: f32,
    ) -> Option<[f32; 2]> {
        let footprint = self.footprint(p)?;
        let distance = |q: [f32; 2]| (q[0] - from[0]).hypot(q[1] - from[1]);
        let margin = (NEXT_TO_MAX_M / CELL_M).ceil() as usize;
        let [r0, c0, r1, c1] = footprint.rows_cols;
        let mut best: Option<([f32; 2], f32)> = None;
        for r in r0.saturating_sub(margin)..=(r1 + margin).min(self.side - 1) {
            for c in c0.saturating_sub(margin)..=(c1 + margin).min(self.side - 1) {
                let q = self.centre(r, c);
                let d = distance(q);
                if best.is_none_or(|(_, b)| d < b)
                    && self.is_clear(q, clear_m)
                    && self.beside(&footprint, q)
                {
                    best = Some((q, d));
                }
            }
        }
        let (q, d) = best?;
        match previous {
            Some(t)
                if distance(t) <= d + keep_m
                    && self.is_clear(t, clear_m)
                    && self.beside(&footprint, t) =>
            {
                Some(t)
            }
            _ => Some(q),
        }
    }

    /// The highest top the map knows within `around` (m) of `from` and along the way to
    /// `to` (up to `ahead` m of it, `half_width` m to either side), and whether it knows
    /// every cell there (`false` also when one lies outside the map or an input is not
    /// finite).
    pub fn top_along(
        &self,
        from: [f32; 2],
        to: [f32; 2],
        half_width: f32,
        around: f32,
        ahead: f32,
    ) -> (f32, bool) {
        let (mut top, mut complete) = (0.0f32, true);
        let mut look = |q: [f32; 2]| match self.height_at(q) {
            Some(h) => top = top.max(h),
            None => complete = false,
        };
        let steps = (around / CELL_M).ceil() as i32;
        for i in -steps..=steps {
            for j in -steps..=steps {
                let (dn, de) = (i as f32 * CELL_M, j as f32 * CELL_M);
                if dn.hypot(de) <= around {
                    look([from[0] + dn, from[1] + de]);
                }
            }
        }
        let (dn, de) = (to[0] - from[0], to[1] - from[1]);
        let dist = dn.hypot(de);
        if !(dist.is_finite() && ahead.is_finite()) {
            return (top, false);
        }
        if dist >= 1e-3 {
            let (un, ue) = (dn / dist, de / dist);
            // to the end of the way, and a corridor's width past it
            let len = (dist + half_width).min(ahead);
            let sides = (half_width / CELL_M).ceil() as i32;
            let mut t = 0.0;
            while t <= len {
                for k in -sides..=sides {
                    let side = k as f32 * CELL_M;
                    look([from[0] + un * t - ue * side, from[1] + ue * t + un * side]);
                }
                t += CELL_M;
            }
        }
        (top, complete)
    }

    /// The centre of the cell nearest to `p`, within `within` (m), whose surroundings
    /// within `clear_m` are observed free ground.
    pub fn nearest_clear(&self, p: [f32; 2], within: f32, clear_m: f32) -> Option<[f32; 2]> {
        let (pr, pc) = self.cell(p)?;
        let reach = (within / CELL_M).ceil() as usize;
        let mut best: Option<([f32; 2], f32)> = None;
        for r in pr.saturating_sub(reach)..=(pr + reach).min(self.side - 1) {
            for c in pc.saturating_sub(reach)..=(pc + reach).min(self.side - 1) {
                let q = self.centre(r, c);
                let d = (q[0] - p[0]).hypot(q[1] - p[1]);
                if d <= within && best.is_none_or(|(_, b)| d < b) && self.is_clear(q, clear_m) {
                    best = Some((q, d));
                }
            }
        }
        best.map(|(q, _)| q)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An ego grid at `origin` where `f(N, E)` gives each cell's height (`None` unknown).
    fn grid(origin: [f32; 2], f: impl Fn([f32; 2]) -> Option<u8>) -> OccupancyGrid {
        let mut g = OccupancyGrid::observed(origin, 2.0);
        let half = (OCCUPANCY_SIDE / 2) as f32;
        for (i, cell) in g.cells.iter_mut().enumerate() {
            let (r, c) = (i / OCCUPANCY_SIDE, i % OCCUPANCY_SIDE);
            let p = [
                origin[0] + (r as f32 - half + 0.5) * 2.0,
                origin[1] + (c as f32 - half + 0.5) * 2.0,
            ];
            *cell = f(p).unwrap_or(OCCUPANCY_UNKNOWN);
        }
        g
    }

    /// A 40 m x 40 m building of 25 m at N, E in [100, 140], free ground around.
    fn building(p: [f32; 2]) -> Option<u8> {
        let inside = (100.0..140.0).contains(&p[0]) && (100.0..140.0).contains(&p[1]);
        Some(if inside { 25 } else { 0 })
    }

    fn map_with_building() -> HeightMap {
        let mut m = HeightMap::covering([-200.0, -200.0], [200.0, 200.0]);
        // seen from the approach, north-west of it: what lies under the vehicle is unknown
        m.absorb(&grid([80.0, 80.0], |p| {
            let under = (p[0] - 80.0).hypot(p[1] - 80.0) < 10.0;
            (!under).then(|| building(p)).flatten()
        }));
        m
    }

    #[test]
    fn keeps_the_highest_top_and_what_later_frames_do_not_see() {
        let mut m = HeightMap::covering([-200.0, -200.0], [200.0, 200.0]);
        assert_eq!(m.height_at([120.0, 120.0]), None);
        m.absorb(&grid([100.0, 100.0], building));
        assert_eq!(m.height_at([120.0, 120.0]), Some(25.0));
        assert_eq!(m.height_at([90.0, 90.0]), Some(0.0));
        // a later frame seeing only free ground there, and nothing of the roof
        // (its cells straddle the map's, so the wall's cells get a free reading too)
        m.absorb(&grid([60.0, 60.0], |p| (p[0] < 103.0).then_some(0)));
        assert_eq!(m.height_at([120.0, 120.0]), Some(25.0), "the roof stays");
        assert_eq!(
            m.height_at([101.5, 101.5]),
            Some(25.0),
            "the higher reading wins"
        );
        assert!(m.is_clear([90.0, 90.0], 4.0));
        assert!(!m.is_clear([98.0, 98.0], 4.0), "4 m from the wall");
        assert!(!m.is_clear([-150.0, -150.0], 4.0), "never observed");
        assert_eq!(m.height_at([500.0, 0.0]), None, "outside the map");
    }

    #[test]
    fn the_footprint_is_the_connected_block_at_the_sighting() {
        let mut m = map_with_building();
        // a sighting on the far side of the roof, as a long range reads it
        let f = m.footprint([138.0, 139.0]).unwrap();
        assert_eq!(f.cells, 20 * 20);
        // one beyond the roof's edge by a few metres still finds it
        let f = m.footprint([146.0, 120.0]).unwrap();
        assert_eq!(f.cells, 400);
        // nothing there: the footprint is the sighting's cell
        assert_eq!(m.footprint([0.0, 0.0]).unwrap().cells, 0);
    }

    #[test]
    fn a_touchdown_next_to_a_building_is_beside_it_on_the_approach_side_never_on_it() {
        let mut m = map_with_building();
        let from = [60.0, 60.0];
        let t = m.next_to([130.0, 130.0], from, 4.0, None, 0.0).unwrap();
        let on_roof =
            |t: [f32; 2]| (100.0..140.0).contains(&t[0]) && (100.0..140.0).contains(&t[1]);
        assert!(!on_roof(t), "{t:?}");
        // clear of the walls (4 m, less a cell's slack), beside the building by at most
        // 12 m, on the near side
        let gap = (100.0 - t[0]).max(0.0).hypot((100.0 - t[1]).max(0.0));
        assert!((2.0..=12.0 + CELL_M).contains(&gap), "{t:?} {gap}");
        assert!(t[0] < 100.0 && t[1] < 100.0, "{t:?}");
        // kept while it qualifies, even when the sighting moves a little
        assert_eq!(m.next_to([120.0, 125.0], from, 4.0, Some(t), 4.0), Some(t));
        // a point farther than the best by more than `keep_m` is given up, however long
        // it was kept
        let far = [t[0] + 16.0, t[1] - 4.0];
        assert!(m.is_clear(far, 4.0));
        assert_eq!(
            m.next_to([130.0, 130.0], from, 4.0, Some(far), 4.0),
            Some(t)
        );
        assert_eq!(
            m.next_to([130.0, 130.0], from, 4.0, Some(far), f32::INFINITY),
            Some(far)
        );
        // a previous point on the roof never survives
        let roof = [110.0, 110.0];
        let again = m.next_to([130.0, 130.0], from, 4.0, Some(roof), f32::INFINITY);
        assert_eq!(again, Some(t));
    }

    #[test]
    fn a_board_faces_across_its_long_side() {
        // a sign board 12 m long east-west, 1 m thick, 8 m tall at N 50, E 70..82
        let mut m = HeightMap::covering([-200.0, -200.0], [200.0, 200.0]);
        m.absorb(&grid([30.0, 76.0], |p| {
            Some(
                if (49.0..51.0).contains(&p[0]) && (70.0..82.0).contains(&p[1]) {
                    8
                } else {
                    0
                },
            )
        }));
        let (centre, normal) = m.board([52.0, 75.0]).expect("a board");
        assert_eq!(normal, [1.0, 0.0], "its faces look north and south");
        assert!(
            (centre[0] - 50.0).abs() <= 2.0 && (centre[1] - 76.0).abs() <= 2.0,
            "{centre:?}"
        );
        // turned a quarter: faces east and west
        let mut m = HeightMap::covering([-200.0, -200.0], [200.0, 200.0]);
        m.absorb(&grid([50.0, 50.0], |p| {
            Some(
                if (70.0..82.0).contains(&p[0]) && (49.0..51.0).contains(&p[1]) {
                    8
                } else {
                    0
                },
            )
        }));
        assert_eq!(m.board([76.0, 52.0]).unwrap().1, [0.0, 1.0]);
        // a square building is no board; nothing seen, no board
        let mut m = map_with_building();
        assert_eq!(m.board([120.0, 120.0]), None);
        assert_eq!(m.board([0.0, 0.0]), None);
    }

    #[test]
    fn no_observed_ground_no_touchdown() {
        let mut m = HeightMap::covering([-200.0, -200.0], [200.0, 200.0]);
        m.absorb(&grid([120.0, 120.0], |p| {
            ((100.0..140.0).contains(&p[0]) && (100.0..140.0).contains(&p[1])).then_some(25)
        }));
        assert_eq!(m.next_to([120.0, 120.0], [0.0, 0.0], 4.0, None, 0.0), None);
        assert_eq!(m.nearest_clear([120.0, 120.0], 30.0, 4.0), None);
    }

    #[test]
    fn the_nearest_clear_ground_from_over_a_roof_is_off_it() {
        let m = map_with_building();
        let q = m.nearest_clear([104.0, 110.0], 30.0, 4.0).unwrap();
        // the nearest wall is the one at N = 100
        assert!(
            (92.0..=98.0).contains(&q[0]) && (q[1] - 110.0).abs() <= 2.0,
            "{q:?}"
        );
    }

    #[test]
    fn no_obstacle_near_counts_unknown_ground_free_and_a_wall_a_cell_away_not() {
        let m = map_with_building();
        // under the vehicle of the approach: never observed, free as the gate counts it
        assert_eq!(m.height_at([80.0, 80.0]), None);
        assert!(m.no_obstacle_near([80.0, 80.0], CELL_M));
        assert!(!m.is_clear([80.0, 80.0], CELL_M));
        // observed ground a cell off the wall at N = 100, and the wall's own cell
        assert!(!m.no_obstacle_near([99.0, 110.0], CELL_M));
        assert!(m.no_obstacle_near([95.0, 110.0], CELL_M));
        assert!(!m.no_obstacle_near([104.0, 110.0], 0.0));
    }

    #[test]
    fn the_top_along_a_way_needs_every_cell_observed() {
        let m = map_with_building();
        // from the north-west toward the building: its roof is on the way
        assert_eq!(
            m.top_along([60.0, 120.0], [130.0, 120.0], 4.0, 8.0, 80.0),
            (25.0, true)
        );
        // only 30 m of the way: free ground
        assert_eq!(
            m.top_along([50.0, 120.0], [130.0, 120.0], 4.0, 8.0, 30.0),
            (0.0, true)
        );
        // a way that ends at the wall still sees it
        assert_eq!(
            m.top_along([60.0, 120.0], [99.0, 120.0], 4.0, 0.0, 80.0).0,
            25.0
        );
        // around the vehicle the map saw nothing (it was under it)
        assert_eq!(
            m.top_along([80.0, 80.0], [80.0, 0.0], 4.0, 8.0, 30.0),
            (0.0, false)
        );
        assert!(!m.top_along([80.0, 80.0], [f32::NAN, 0.0], 4.0, 0.0, 30.0).1);
    }

    #[test]
    fn odd_inputs_give_a_small_map_not_a_panic() {
        let mut m = HeightMap::covering([f32::NAN, 0.0], [f32::INFINITY, 1.0]);
        m.absorb(&grid([0.0, 0.0], building));
        assert!(
            m.next_to([f32::NAN, 0.0], [0.0, 0.0], 4.0, None, 0.0)
                .is_none()
        );
        let mut huge = HeightMap::covering([-1e6, -1e6], [1e6, 1e6]);
        assert_eq!(huge.side, MAX_SIDE);
        huge.absorb(&grid([100.0, 100.0], building));
        assert_eq!(huge.height_at([120.0, 120.0]), Some(25.0));
    }
}
