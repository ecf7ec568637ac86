//! Image preprocessing shared by the vision models: letterboxing into a planar float tensor.

/// Where a letterboxed image lies inside the network input: `input = image * scale + pad`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Letterbox {
    /// Scale from image pixels to input pixels.
    pub scale: f32,
    /// Horizontal padding (input pixels).
    pub pad_x: f32,
    /// Vertical padding (input pixels).
    pub pad_y: f32,
}

impl Letterbox {
    /// Map a box `[x, y, w, h]` in input pixels back to image pixels.
    pub fn to_image(&self, b: [f32; 4]) -> [f32; 4] {
        [
            (b[0] - self.pad_x) / self.scale,
            (b[1] - self.pad_y) / self.scale,
            b[2] / self.scale,
            b[3] / self.scale,
        ]
    }
}

/// Why packed RGB8 `rgb` is not a `width` x `height` image, if it is not.
pub fn rgb8_mismatch(rgb: &[u8], width: usize, height: usize) -> Option<String> {
    let needed = width * height * 3;
    (rgb.len() != needed).then(|| {
        format!(
            "an RGB8 image of {width}x{height} needs {needed} bytes, got {}",
            rgb.len()
        )
    })
}

/// Resize packed RGB8 `rgb` (`width` x `height`) into `dst` as planar CHW floats in [0, 1]
/// of size `side` x `side`, keeping the aspect ratio and padding with grey (0.5), bilinear.
///
/// `dst` must hold `3 * side * side` values. Returns where the image went.
pub fn letterbox_chw(
    rgb: &[u8],
    width: usize,
    height: usize,
    side: usize,
    dst: &mut [f32],
) -> Letterbox {
    let plane = side * side;
    dst[..3 * plane].fill(0.5);
    if width == 0 || height == 0 || rgb.len() < width * height * 3 {
        return Letterbox {
            scale: 1.0,
            pad_x: 0.0,
            pad_y: 0.0,
        };
    }
    let scale = (side as f32 / width as f32).min(side as f32 / height as f32);
    let nw = ((width as f32 * scale).round() as usize).clamp(1, side);
    let nh = ((height as f32 * scale).round() as usize).clamp(1, side);
    let (ox, oy) = ((side - nw) / 2, (side - nh) / 2);
    let sx = width as f32 / nw as f32;
    let sy = height as f32 / nh as f32;
    for y in 0..nh {
        let fy = ((y as f32 + 0.5) * sy - 0.5).clamp(0.0, (height - 1) as f32);
        let y0 = fy as usize;
        let y1 = (y0 + 1).min(height - 1);
        let wy = fy - y0 as f32;
        for x in 0..nw {
            let fx = ((x as f32 + 0.5) * sx - 0.5).clamp(0.0, (width - 1) as f32);
            let x0 = fx as usize;
            let x1 = (x0 + 1).min(width - 1);
            let wx = fx - x0 as f32;
            let at = |xx: usize, yy: usize, c: usize| rgb[(yy * width + xx) * 3 + c] as f32;
            let o = (oy + y) * side + ox + x;
            for c in 0..3 {
                let top = at(x0, y0, c) * (1.0 - wx) + at(x1, y0, c) * wx;
                let bottom = at(x0, y1, c) * (1.0 - wx) + at(x1, y1, c) * wx;
                dst[c * plane + o] = (top * (1.0 - wy) + bottom * wy) / 255.0;
            }
        }
    }
    Letterbox {
        scale: nw as f32 / width as f32,
        pad_x: ox as f32,
        pad_y: oy as f32,
    }
}
