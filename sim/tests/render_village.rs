//! FPV frames of the village: colours, depth, sky, lettering, and argument checks.

use aeris_sim::render::{
    CAMERA_PITCH_RAD, CameraModel, CameraModelError, FACE_SHADES, MAX_DEPTH_M, RenderError,
    Renderer, ppm_bytes, shaded,
};
use aeris_sim::world::{World, palette};

const W: u32 = 320;
const H: u32 = 240;
const HFOV: f32 = std::f32::consts::FRAC_PI_2;

struct Frame {
    rgb: Vec<u8>,
    depth: Vec<u8>,
}

impl Frame {
    fn px(&self, col: u32, row: u32) -> [u8; 3] {
        let i = (row * W + col) as usize * 3;
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }
    fn depth_mm(&self, col: u32, row: u32) -> u16 {
        let i = (row * W + col) as usize * 2;
        u16::from_le_bytes([self.depth[i], self.depth[i + 1]])
    }
}

fn render(pos: [f32; 3], yaw: f32) -> (Renderer, World, Frame) {
    let world = World::builtin("village").unwrap();
    let r = Renderer::new(W, H, HFOV).unwrap();
    let mut f = Frame {
        rgb: vec![0; r.rgb_len()],
        depth: vec![0; r.depth_len()],
    };
    r.render(&world, pos, yaw, &mut f.rgb, &mut f.depth)
        .unwrap();
    (r, world, f)
}

/// Save a frame as PPM in a per-process temp dir, returning its size. The file is removed
/// again unless `AERIS_KEEP_FRAMES` is set (to look at it).
fn save(name: &str, f: &Frame) -> u64 {
    let dir = std::env::temp_dir().join(format!("aeris-render-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("{name}.ppm"));
    std::fs::write(&path, ppm_bytes(W, H, &f.rgb).unwrap()).unwrap();
    let len = std::fs::metadata(&path).unwrap().len();
    if std::env::var_os("AERIS_KEEP_FRAMES").is_some() {
        eprintln!("saved {}", path.display());
    } else {
        let _ = std::fs::remove_file(&path);
        let _ = std::fs::remove_dir(&dir);
    }
    len
}

fn is_shade_of(px: [u8; 3], colour: [u8; 3]) -> bool {
    FACE_SHADES.iter().any(|s| shaded(colour, *s) == px)
}

#[test]
fn red_roofed_building_fills_the_centre_looking_north() {
    let (_, _, f) = render([50.0, 18.0, 12.0], 0.0);
    assert!(save("north_red_roof", &f) > (W * H * 3) as u64);
    let (mut house, mut total) = (0, 0);
    for row in H / 2 - 15..H / 2 + 15 {
        for col in W / 2 - 20..W / 2 + 20 {
            total += 1;
            let p = f.px(col, row);
            if is_shade_of(p, palette::BEIGE_WALL) || is_shade_of(p, palette::RED_ROOF) {
                house += 1;
            }
        }
    }
    assert!(
        house * 10 >= total * 9,
        "only {house}/{total} centre pixels are the red-roofed building"
    );
    // the eaves band shows red above the beige wall
    let red = f
        .rgb
        .chunks_exact(3)
        .filter(|p| is_shade_of([p[0], p[1], p[2]], palette::RED_ROOF))
        .count();
    assert!(red > 100, "{red} red pixels");
}

#[test]
fn centre_depth_matches_the_raycast() {
    let (r, world, f) = render([50.0, 18.0, 12.0], 0.0);
    let (col, row) = (W / 2, H / 2);
    let ray = r.camera().pixel_ray(col, row);
    let norm = (ray[0] * ray[0] + ray[1] * ray[1] + ray[2] * ray[2]).sqrt();
    let dir = [ray[0] / norm, ray[1] / norm, ray[2] / norm];
    let hit = world.raycast([50.0, 18.0, 12.0], dir, 1000.0).unwrap();
    let expected_mm = hit.distance / norm * 1000.0;
    let got = f.depth_mm(col, row) as f32;
    assert!(
        (got - expected_mm).abs() <= 1.0,
        "depth {got} mm, raycast z {expected_mm} mm"
    );
    // the centre ray points 15 degrees down: it meets the wall 22 m north at ~6 m height
    let north = got / 1000.0 * ray[0];
    assert!((north - 22.0).abs() < 0.01, "{north}");
    assert!((12.0 + got / 1000.0 * ray[2] - 6.1).abs() < 0.2);
}

#[test]
fn depth_back_projects_onto_the_surfaces() {
    let pos = [50.0, 18.0, 12.0];
    let (r, world, f) = render(pos, 0.3);
    let cam = r.camera();
    let mut checked = 0;
    for row in (0..H).step_by(7) {
        for col in (0..W).step_by(7) {
            let z = f.depth_mm(col, row) as f32 / 1000.0;
            if z == 0.0 {
                continue;
            }
            let ray = aeris_sim::render::body_to_world(cam.pixel_ray(col, row), 0.3);
            let p = [
                pos[0] + z * ray[0],
                pos[1] + z * ray[1],
                pos[2] + z * ray[2],
            ];
            // highest obstacle within 5 cm (a wall point may round to just outside its box)
            let mut top: f32 = 0.0;
            for dn in [-0.05, 0.0, 0.05] {
                for de in [-0.05, 0.0, 0.05] {
                    top = top.max(world.obstacle_top_at(p[0] + dn, p[1] + de));
                }
            }
            // every return lies on the ground or on/under an obstacle top
            assert!(
                p[2] > -0.05 && p[2] <= top.max(0.05) + 0.05,
                "{p:?} top {top}"
            );
            checked += 1;
        }
    }
    assert!(checked > 500);
}

#[test]
fn sky_has_no_return_and_far_ground_is_capped() {
    let (_, _, f) = render([0.0, -150.0, 50.0], -std::f32::consts::FRAC_PI_2);
    // top row looks above the horizon (pitch 15 deg, vertical half-fov ~37 deg)
    for col in 0..W {
        assert_eq!(f.depth_mm(col, 0), 0);
        assert_ne!(f.px(col, 0), palette::GRASS);
    }
    let far_grass = (0..H)
        .flat_map(|row| (0..W).map(move |col| (col, row)))
        .filter(|&(c, r)| f.px(c, r) == palette::GRASS && f.depth_mm(c, r) == 0)
        .count();
    assert!(
        far_grass > 0,
        "grass beyond {MAX_DEPTH_M} m reads no return"
    );
    assert!(f.depth_mm(W / 2, H - 1) > 0, "near ground has depth");
}

#[test]
fn the_sign_is_yellow_with_lettering() {
    // north of the sign, facing south towards it
    let (_, _, f) = render([48.0, 88.0, 6.0], std::f32::consts::PI);
    save("sign", &f);
    let yellow = f
        .rgb
        .chunks_exact(3)
        .filter(|p| is_shade_of([p[0], p[1], p[2]], palette::SIGN_YELLOW))
        .count();
    let text = f
        .rgb
        .chunks_exact(3)
        .filter(|p| is_shade_of([p[0], p[1], p[2]], palette::SIGN_TEXT))
        .count();
    assert!(yellow > 500, "{yellow} yellow pixels");
    assert!(text > 20, "{text} lettering pixels");
    assert!(text < yellow);
}

#[test]
fn pitch_is_the_documented_constant() {
    let r = Renderer::new(W, H, HFOV).unwrap();
    assert_eq!(r.camera().pitch, CAMERA_PITCH_RAD);
    // the optical axis (image centre) points down by the pitch
    let ray = r.camera().ray_at(W as f32 / 2.0, H as f32 / 2.0);
    assert!((ray[2].atan2(ray[0]) + CAMERA_PITCH_RAD).abs() < 1e-6);
}

#[test]
fn bad_arguments_are_errors() {
    assert!(matches!(
        Renderer::new(0, 10, 1.0),
        Err(RenderError::Camera(CameraModelError::BadGeometry { .. }))
    ));
    assert!(matches!(
        CameraModel::new(10, 10, 3.5),
        Err(CameraModelError::BadGeometry { .. })
    ));
    let world = World::builtin("village").unwrap();
    let r = Renderer::new(8, 6, 1.0).unwrap();
    let mut rgb = vec![0; 8 * 6 * 3];
    let mut depth = vec![0; 8 * 6 * 2 - 1];
    assert!(matches!(
        r.render(&world, [0.0, 0.0, 5.0], 0.0, &mut rgb, &mut depth),
        Err(RenderError::BufferSize { which: "depth", .. })
    ));
    let mut depth = vec![0; 8 * 6 * 2];
    assert_eq!(
        r.render(&world, [f32::NAN, 0.0, 5.0], 0.0, &mut rgb, &mut depth),
        Err(RenderError::BadPose)
    );
    assert!(
        r.render(&world, [0.0, 0.0, 5.0], 0.0, &mut rgb, &mut depth)
            .is_ok()
    );
    assert!(ppm_bytes(8, 6, &rgb[1..]).is_err());
}
