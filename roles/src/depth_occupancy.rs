//! Depth frames -> the 2.5-D occupancy block of S_t: every depth return back-projected
//! with the frame's pose, field of view and the shared camera model
//! ([`aeris_geometry::CameraModel`] with [`CAMERA_PITCH_RAD`]) into `[N, E, U]`; each cell
//! of the 64x64 grid centred on the camera keeps the highest obstacle top seen. The
//! `occupancy` role (variant `depth`) publishes it alone; the simulator's geometric
//! perception fills it beside its other blocks.

use aeris_geometry::{CAMERA_MOUNT_HEIGHT_M, CAMERA_PITCH_RAD, CameraModel, CameraModelError};
use aeris_schemas::{
    FrameFormat, FrameHeader, OCCUPANCY_UNKNOWN, OccupancyStatus, PerceptionState, block,
};

/// Back-projected points lower than this (m) are ground.
pub const GROUND_EPS_M: f32 = 0.5;
/// Occupancy cell size (m).
pub const OCCUPANCY_RESOLUTION_M: f32 = 2.0;

/// Why a depth frame gave no occupancy block.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum OccupancyError {
    /// The header does not describe a depth payload of this size.
    #[error("not a depth frame of the size its header gives")]
    NotDepth,
    /// The camera geometry in the header is unusable.
    #[error("camera geometry: {0}")]
    Geometry(CameraModelError),
}

/// Fill only the occupancy block of `state` (and its frame fields) from one depth frame:
/// the occupancy role's whole work. Never allocates.
pub fn occupancy_from_depth(
    depth: &[u8],
    header: &FrameHeader,
    state: &mut PerceptionState,
) -> Result<(), OccupancyError> {
    if header.validate(depth.len()) != Ok(FrameFormat::DepthU16Mm) {
        return Err(OccupancyError::NotDepth);
    }
    let camera =
        CameraModel::with_pitch(header.width, header.height, header.hfov, CAMERA_PITCH_RAD)
            .map_err(OccupancyError::Geometry)?;
    fill_occupancy(depth, header, &camera, state);
    let p = header.camera_position;
    state.frame_seq = header.seq;
    state.capture_ns = header.capture_ns;
    state.position = [p[0], p[1], p[2] - CAMERA_MOUNT_HEIGHT_M];
    state.yaw = header.camera_yaw;
    state.blocks = block::OCCUPANCY;
    Ok(())
}

/// Back-project every return of `depth` (u16 LE mm z-depth, described by `header`, seen
/// through `camera`) into `state`'s occupancy grid: a [`OCCUPANCY_RESOLUTION_M`] grid
/// centred on the camera, each cell the highest obstacle top seen (ground returns, below
/// [`GROUND_EPS_M`], give 0; cells without returns stay [`OCCUPANCY_UNKNOWN`]), marked
/// [`OccupancyStatus::Present`]: it comes from this depth frame. Touches nothing else of
/// `state`. Never allocates.
pub fn fill_occupancy(
    depth: &[u8],
    header: &FrameHeader,
    camera: &CameraModel,
    state: &mut PerceptionState,
) {
    let cam = header.camera_position;
    let grid = &mut state.occupancy;
    grid.origin = [cam[0], cam[1]];
    grid.resolution_m = OCCUPANCY_RESOLUTION_M;
    grid.status = OccupancyStatus::Present as u8;
    grid.reserved = [0; 3];
    grid.cells.fill(OCCUPANCY_UNKNOWN);
    let w = camera.width as usize;
    let f = camera.focal_px();
    let (sp, cp) = camera.pitch.sin_cos();
    let (sy, cy) = header.camera_yaw.sin_cos();
    let (half_w, half_h) = (0.5 * camera.width as f32, 0.5 * camera.height as f32);
    for (i, dz) in depth.chunks_exact(2).enumerate() {
        let z = u16::from_le_bytes([dz[0], dz[1]]);
        if z == 0 {
            continue;
        }
        let z = z as f32 * 0.001;
        let (col, row) = (i % w, i / w);
        let rx = (col as f32 + 0.5 - half_w) / f;
        let ry = (row as f32 + 0.5 - half_h) / f;
        // the shared camera model (CameraModel::ray_at), inlined with per-frame constants
        let fwd = cp - ry * sp;
        let up = -sp - ry * cp;
        let n = cam[0] + z * (fwd * cy - rx * sy);
        let e = cam[1] + z * (fwd * sy + rx * cy);
        let u = cam[2] + z * up;
        let Some(cell) = grid.cell_of([n, e]) else {
            continue;
        };
        let height = if u < GROUND_EPS_M {
            0
        } else {
            (u + 0.5).min(254.0) as u8
        };
        let c = &mut grid.cells[cell];
        if *c == OCCUPANCY_UNKNOWN || height > *c {
            *c = height;
        }
    }
}
