//! RGB images: visibility panels, error heat maps, labels, PNG output.

use std::{fs::File, io::BufWriter, path::Path};

use crate::LabError;

/// An 8-bit RGB image.
#[derive(Debug, Clone)]
pub struct Picture {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[u8; 3]>,
}

pub const BACKGROUND: [u8; 3] = [28, 34, 52];
/// Surfaces the light's centre does not face: its shading is zero there.
pub const UNLIT: [u8; 3] = [70, 62, 84];

/// A pixel: background (`None`), unlit side (`Some(None)`) or a value.
pub type Pixel = Option<Option<f32>>;

impl Picture {
    pub fn new(width: u32, height: u32, fill: [u8; 3]) -> Self {
        Self { width, height, pixels: vec![fill; (width * height) as usize] }
    }

    /// Visibility as grey (sRGB-encoded so mid-greys look mid).
    pub fn visibility(width: u32, height: u32, values: &[Pixel]) -> Self {
        let pixels = values
            .iter()
            .map(|v| match v {
                Some(Some(v)) => [srgb(*v); 3],
                Some(None) => UNLIT,
                None => BACKGROUND,
            })
            .collect();
        Self { width, height, pixels }
    }

    /// Signed error heat map: black where exact, red where the method is too
    /// bright (leaks), cyan where too dark (umbra over-estimation), saturating at
    /// `full_scale`.
    pub fn error_map(width: u32, height: u32, method: &[Pixel], reference: &[Pixel], full_scale: f32) -> Self {
        let pixels = method
            .iter()
            .zip(reference)
            .map(|(m, r)| match (m, r) {
                (Some(None), _) | (_, Some(None)) => UNLIT,
                (Some(Some(m)), Some(Some(r))) => {
                    let e = ((m - r) / full_scale).clamp(-1.0, 1.0);
                    let a = srgb(e.abs());
                    if !e.is_finite() {
                        [255, 0, 255]
                    } else if e > 0.0 {
                        [a, a / 4, 0]
                    } else {
                        [0, a, a]
                    }
                }
                _ => BACKGROUND,
            })
            .collect();
        Self { width, height, pixels }
    }

    pub fn blit(&mut self, other: &Picture, x0: u32, y0: u32) {
        for y in 0..other.height.min(self.height.saturating_sub(y0)) {
            for x in 0..other.width.min(self.width.saturating_sub(x0)) {
                self.pixels[((y0 + y) * self.width + x0 + x) as usize] = other.pixels[(y * other.width + x) as usize];
            }
        }
    }

    /// Sets one pixel if it lies inside.
    pub fn put(&mut self, x: i64, y: i64, color: [u8; 3]) {
        if x >= 0 && y >= 0 && (x as u32) < self.width && (y as u32) < self.height {
            self.pixels[(y as u32 * self.width + x as u32) as usize] = color;
        }
    }

    pub fn hline(&mut self, x0: u32, x1: u32, y: u32, color: [u8; 3]) {
        for x in x0..=x1 {
            self.put(x as i64, y as i64, color);
        }
    }

    pub fn vline(&mut self, x: u32, y0: u32, y1: u32, color: [u8; 3]) {
        for y in y0..=y1 {
            self.put(x as i64, y as i64, color);
        }
    }

    /// A one-pixel line (DDA), two pixels thick for legibility.
    pub fn line(&mut self, a: (f64, f64), b: (f64, f64), color: [u8; 3]) {
        let steps = (b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil().clamp(1.0, 1e5) as i64;
        for i in 0..=steps {
            let t = i as f64 / steps as f64;
            let (x, y) = (a.0 + (b.0 - a.0) * t, a.1 + (b.1 - a.1) * t);
            self.put(x as i64, y as i64, color);
            self.put(x as i64, y as i64 + 1, color);
        }
    }

    /// A filled disc of radius `r` pixels.
    pub fn disc(&mut self, cx: f64, cy: f64, r: f64, color: [u8; 3]) {
        let n = r.ceil() as i64;
        for dy in -n..=n {
            for dx in -n..=n {
                if ((dx * dx + dy * dy) as f64) <= r * r {
                    self.put(cx as i64 + dx, cy as i64 + dy, color);
                }
            }
        }
    }

    /// Draws `text` with a 3×5 pixel font scaled by `scale`.
    pub fn text(&mut self, text: &str, x0: u32, y0: u32, scale: u32, color: [u8; 3]) {
        let mut x = x0;
        for c in text.chars() {
            let g = glyph(c.to_ascii_lowercase());
            for row in 0..5u32 {
                for col in 0..3u32 {
                    if g >> (14 - (row * 3 + col)) & 1 == 1 {
                        for dy in 0..scale {
                            for dx in 0..scale {
                                let (px, py) = (x + col * scale + dx, y0 + row * scale + dy);
                                if px < self.width && py < self.height {
                                    self.pixels[(py * self.width + px) as usize] = color;
                                }
                            }
                        }
                    }
                }
            }
            x += 4 * scale;
        }
    }

    pub fn save_png(&self, path: &Path) -> Result<(), LabError> {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(|e| LabError::Io(dir.display().to_string(), e))?;
        }
        let file = File::create(path).map_err(|e| LabError::Io(path.display().to_string(), e))?;
        let mut enc = png::Encoder::new(BufWriter::new(file), self.width, self.height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().map_err(|e| LabError::Png(e.to_string()))?;
        let data: Vec<u8> = self.pixels.iter().flatten().copied().collect();
        w.write_image_data(&data).map_err(|e| LabError::Png(e.to_string()))
    }
}

/// One method's panel of a [`strip`].
pub struct Column {
    pub label: String,
    pub values: Vec<Pixel>,
    pub mae: f32,
}

/// Method panels side by side with the ground truth last, each method's
/// signed error map (full scale ±0.5) below it.
pub fn strip(w: u32, h: u32, columns: &[Column], reference: &[Pixel]) -> Picture {
    let label_h = 14;
    let count = columns.len() as u32 + 1;
    let mut pic = Picture::new(count * (w + 4), 2 * (h + label_h) + 4, [12, 12, 16]);
    for (i, c) in columns.iter().enumerate() {
        let x = i as u32 * (w + 4);
        pic.blit(&Picture::visibility(w, h, &c.values), x, label_h);
        // Long labels drop to the small font rather than run into the next panel.
        let scale = if c.label.len() as u32 * 8 + 4 <= w { 2 } else { 1 };
        pic.text(&c.label, x + 2, 3, scale, [230, 230, 230]);
        pic.blit(&Picture::error_map(w, h, &c.values, reference, 0.5), x, 2 * label_h + h + 4);
        pic.text(&format!("mae {:.3}", c.mae), x + 2, label_h + h + 5, 2, [230, 230, 230]);
    }
    let x = columns.len() as u32 * (w + 4);
    pic.blit(&Picture::visibility(w, h, reference), x, label_h);
    pic.text("ground truth", x + 2, 3, 2, [230, 230, 230]);
    pic.text("error: red bright", x + 2, label_h + h + 5, 2, [230, 120, 60]);
    pic.text("cyan dark", x + 2, 2 * label_h + h + 8, 2, [60, 220, 220]);
    pic
}

/// Linear value → sRGB byte (non-finite → 0, clamped to [0, 1]).
pub fn srgb(v: f32) -> u8 {
    let v = if v.is_finite() { v.clamp(0.0, 1.0) } else { 0.0 };
    let s = if v <= 0.0031308 { v * 12.92 } else { 1.055 * v.powf(1.0 / 2.4) - 0.055 };
    (s * 255.0 + 0.5) as u8
}

/// 3×5 glyphs, row-major, most significant bit first (15 bits).
fn glyph(c: char) -> u16 {
    match c {
        'a' => 0b010_101_111_101_101,
        'b' => 0b110_101_110_101_110,
        'c' => 0b011_100_100_100_011,
        'd' => 0b110_101_101_101_110,
        'e' => 0b111_100_110_100_111,
        'f' => 0b111_100_110_100_100,
        'g' => 0b011_100_101_101_011,
        'h' => 0b101_101_111_101_101,
        'i' => 0b111_010_010_010_111,
        'j' => 0b001_001_001_101_010,
        'k' => 0b101_101_110_101_101,
        'l' => 0b100_100_100_100_111,
        'm' => 0b101_111_111_101_101,
        'n' => 0b110_101_101_101_101,
        'o' => 0b010_101_101_101_010,
        'p' => 0b110_101_110_100_100,
        'q' => 0b010_101_101_110_011,
        'r' => 0b110_101_110_101_101,
        's' => 0b011_100_010_001_110,
        't' => 0b111_010_010_010_010,
        'u' => 0b101_101_101_101_111,
        'v' => 0b101_101_101_101_010,
        'w' => 0b101_101_111_111_101,
        'x' => 0b101_101_010_101_101,
        'y' => 0b101_101_010_010_010,
        'z' => 0b111_001_010_100_111,
        '0' => 0b111_101_101_101_111,
        '1' => 0b010_110_010_010_111,
        '2' => 0b110_001_010_100_111,
        '3' => 0b110_001_010_001_110,
        '4' => 0b101_101_111_001_001,
        '5' => 0b111_100_110_001_110,
        '6' => 0b011_100_111_101_111,
        '7' => 0b111_001_010_010_010,
        '8' => 0b111_101_111_101_111,
        '9' => 0b111_101_111_001_110,
        '-' => 0b000_000_111_000_000,
        '.' => 0b000_000_000_000_010,
        ':' => 0b000_010_000_010_000,
        '=' => 0b000_111_000_111_000,
        '/' => 0b001_001_010_100_100,
        '(' => 0b010_100_100_100_010,
        ')' => 0b010_001_001_001_010,
        _ => 0,
    }
}
