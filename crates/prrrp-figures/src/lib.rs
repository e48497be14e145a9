//! A small raster canvas for the report figures of `prrrp identify`: antialiased
//! polylines (solid or dashed), rectangles, polygons, round markers and text in a bundled
//! DejaVu Sans, encoded as PNG. Pure Rust (tiny-skia, ab_glyph, png): no system library.
//!
//! The figures' layout (panels, ticks, labels, legends) is decided by the caller
//! (python/prrrp/canvas.py); this crate only draws, in pixel coordinates (x right, y
//! down, origin at the top-left corner of the image). Drawing the report's three figures
//! takes tens of milliseconds here, against about a second of matplotlib.

use std::collections::HashMap;
use std::fmt;

use ab_glyph::{Font, FontRef, GlyphId, OutlineCurve};
use tiny_skia::{
    Color, FillRule, LineCap, LineJoin, Mask, Paint, Path, PathBuilder, Pixmap, Rect, Stroke,
    StrokeDash, Transform,
};

/// DejaVu Sans (the font matplotlib ships; licence in fonts/LICENSE).
static FONT_BYTES: &[u8] = include_bytes!("../fonts/DejaVuSans.ttf");

/// The largest width or height of a canvas, pixels: a report figure is about 1400 × 600.
pub const MAX_SIDE: u32 = 16_384;

/// An 8-bit RGBA colour, not premultiplied.
pub type Rgba = [u8; 4];

/// What can go wrong making or encoding a canvas.
#[derive(Debug, Clone, PartialEq)]
pub enum CanvasError {
    /// A width or height of 0 or above [`MAX_SIDE`].
    Size { width: u32, height: u32 },
    /// Coordinate arrays of different lengths.
    Lengths { xs: usize, ys: usize },
    /// A width, radius or size that is not finite and positive (or a dash pattern that is not).
    Parameter { what: &'static str, value: f64 },
    /// The PNG encoder failed (e.g. out of memory).
    Encode(String),
}

impl fmt::Display for CanvasError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Size { width, height } => write!(
                f,
                "a canvas must be 1..={MAX_SIDE} pixels wide and high, got {width} × {height}"
            ),
            Self::Lengths { xs, ys } => {
                write!(f, "x and y differ in length ({xs} and {ys} points)")
            }
            Self::Parameter { what, value } => {
                write!(f, "{what} must be finite and > 0, got {value}")
            }
            Self::Encode(why) => write!(f, "PNG encoding failed: {why}"),
        }
    }
}

impl std::error::Error for CanvasError {}

/// Horizontal anchor of a text: its left end, centre or right end at the given point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HAlign {
    Left,
    Center,
    Right,
}

/// Vertical anchor of a text (before rotation): the font's ascender line, the middle
/// between ascender and descender, the baseline, or the descender line at the point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VAlign {
    Top,
    Center,
    Baseline,
    Bottom,
}

/// Width and vertical extent of a laid-out text, pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TextExtent {
    /// Advance width of the whole text (left end to right end).
    pub width: f32,
    /// Height of the font's ascender above the baseline.
    pub ascent: f32,
    /// Depth of the font's descender below the baseline (positive).
    pub descent: f32,
}

/// An RGBA image, white when made, that shapes are drawn on (see the crate docs).
pub struct Canvas {
    pixmap: Pixmap,
    font: FontRef<'static>,
    glyphs: HashMap<GlyphId, Option<Path>>,
    clip: Option<([i32; 4], Mask)>,
}

/// Coordinate arrays pair up point by point.
fn same_length(xs: &[f64], ys: &[f64]) -> Result<(), CanvasError> {
    if xs.len() == ys.len() {
        return Ok(());
    }
    Err(CanvasError::Lengths {
        xs: xs.len(),
        ys: ys.len(),
    })
}

/// The rectangle between two opposite corners `[x0, y0, x1, y1]` in any order; None when
/// it is empty or not finite.
fn rect([x0, y0, x1, y1]: [f32; 4]) -> Option<Rect> {
    Rect::from_ltrb(x0.min(x1), y0.min(y1), x0.max(x1), y0.max(y1))
}

fn check_positive(what: &'static str, value: f32) -> Result<(), CanvasError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(CanvasError::Parameter {
            what,
            value: f64::from(value),
        })
    }
}

fn paint(color: Rgba) -> Paint<'static> {
    let mut p = Paint::default();
    p.set_color(Color::from_rgba8(color[0], color[1], color[2], color[3]));
    p.anti_alias = true;
    p
}

impl Canvas {
    /// A white canvas of `width` × `height` pixels.
    pub fn new(width: u32, height: u32) -> Result<Self, CanvasError> {
        if width == 0 || height == 0 || width > MAX_SIDE || height > MAX_SIDE {
            return Err(CanvasError::Size { width, height });
        }
        let mut pixmap = Pixmap::new(width, height).ok_or(CanvasError::Size { width, height })?;
        pixmap.fill(Color::WHITE);
        // The bundled file is a valid font (tested); a failure here is a build defect.
        let font = FontRef::try_from_slice(FONT_BYTES).expect("the bundled font parses");
        Ok(Self {
            pixmap,
            font,
            glyphs: HashMap::new(),
            clip: None,
        })
    }

    /// Width and height, pixels.
    pub fn size(&self) -> (u32, u32) {
        (self.pixmap.width(), self.pixmap.height())
    }

    /// Restricts the shapes drawn next (not the text) to the rectangle from (x0, y0) to
    /// (x1, y1), pixels (rounded outwards), or lifts the restriction (None): a panel's
    /// data stay inside its frame.
    pub fn set_clip(&mut self, rect: Option<[f32; 4]>) {
        let Some([x0, y0, x1, y1]) = rect else {
            self.clip = None;
            return;
        };
        let (w, h) = self.size();
        let key = [
            x0.min(x1).floor() as i32,
            y0.min(y1).floor() as i32,
            x0.max(x1).ceil() as i32,
            y0.max(y1).ceil() as i32,
        ];
        if self.clip.as_ref().is_some_and(|(k, _)| *k == key) {
            return;
        }
        let mut mask = Mask::new(w, h).expect("same size as the canvas");
        if let Some(r) = Rect::from_ltrb(key[0] as f32, key[1] as f32, key[2] as f32, key[3] as f32)
        {
            mask.fill_path(
                &PathBuilder::from_rect(r),
                FillRule::Winding,
                false,
                Transform::identity(),
            );
        }
        self.clip = Some((key, mask));
    }

    /// A line through the points (xs[i], ys[i]), pixels, `width` pixels wide, in `color`;
    /// `dash` = [on, off, ...] lengths in pixels (empty: solid). A non-finite coordinate
    /// breaks the line there.
    pub fn polyline(
        &mut self,
        xs: &[f64],
        ys: &[f64],
        color: Rgba,
        width: f32,
        dash: &[f32],
    ) -> Result<(), CanvasError> {
        same_length(xs, ys)?;
        check_positive("a line width", width)?;
        let dash = if dash.is_empty() {
            None
        } else {
            for &d in dash {
                check_positive("a dash length", d)?;
            }
            Some(
                StrokeDash::new(dash.to_vec(), 0.0).ok_or(CanvasError::Parameter {
                    what: "a dash pattern (an even number of lengths)",
                    value: dash.len() as f64,
                })?,
            )
        };
        let mut pb = PathBuilder::new();
        let mut open = false;
        for (&x, &y) in xs.iter().zip(ys) {
            if !(x.is_finite() && y.is_finite()) {
                open = false;
                continue;
            }
            let (x, y) = (x as f32, y as f32);
            if open {
                pb.line_to(x, y);
            } else {
                pb.move_to(x, y);
                open = true;
            }
        }
        let Some(path) = pb.finish() else {
            return Ok(()); // fewer than two finite points: nothing to draw
        };
        let stroke = Stroke {
            width,
            line_cap: LineCap::Butt,
            line_join: LineJoin::Round,
            dash,
            ..Stroke::default()
        };
        let p = paint(color);
        let mask = self.clip.as_ref().map(|(_, m)| m);
        self.pixmap
            .stroke_path(&path, &p, &stroke, Transform::identity(), mask);
        Ok(())
    }

    /// A filled rectangle between the corners (x0, y0) and (x1, y1) of `corners` = [x0, y0,
    /// x1, y1], pixels.
    pub fn fill_rect(&mut self, corners: [f32; 4], color: Rgba) {
        if let Some(r) = rect(corners) {
            let p = paint(color);
            let mask = self.clip.as_ref().map(|(_, m)| m);
            self.pixmap.fill_rect(r, &p, Transform::identity(), mask);
        }
    }

    /// The outline of the rectangle of `corners` (as [`Canvas::fill_rect`]'s), `width`
    /// pixels wide, centred on its edges.
    pub fn stroke_rect(
        &mut self,
        corners: [f32; 4],
        color: Rgba,
        width: f32,
    ) -> Result<(), CanvasError> {
        check_positive("a line width", width)?;
        if let Some(r) = rect(corners) {
            let stroke = Stroke {
                width,
                line_join: LineJoin::Miter,
                ..Stroke::default()
            };
            let p = paint(color);
            let mask = self.clip.as_ref().map(|(_, m)| m);
            let path = PathBuilder::from_rect(r);
            self.pixmap
                .stroke_path(&path, &p, &stroke, Transform::identity(), mask);
        }
        Ok(())
    }

    /// The polygon through the points (closed; non-finite points skipped), filled.
    pub fn fill_polygon(&mut self, xs: &[f64], ys: &[f64], color: Rgba) -> Result<(), CanvasError> {
        same_length(xs, ys)?;
        let mut pb = PathBuilder::new();
        let mut first = true;
        for (&x, &y) in xs.iter().zip(ys) {
            if !(x.is_finite() && y.is_finite()) {
                continue;
            }
            if first {
                pb.move_to(x as f32, y as f32);
                first = false;
            } else {
                pb.line_to(x as f32, y as f32);
            }
        }
        pb.close();
        if let Some(path) = pb.finish() {
            let p = paint(color);
            let mask = self.clip.as_ref().map(|(_, m)| m);
            self.pixmap
                .fill_path(&path, &p, FillRule::Winding, Transform::identity(), mask);
        }
        Ok(())
    }

    /// A filled disc of `radius` pixels at each point (non-finite points skipped), each
    /// drawn over the others (translucent colours darken where discs overlap), inside the
    /// clip. Each pixel gets the disc's coverage estimated from its centre's distance,
    /// clamp(r + ½ − d, 0, 1): a few operations per pixel where a path per disc cost
    /// ~1.5 µs (the friction figure draws tens of thousands).
    pub fn markers(
        &mut self,
        xs: &[f64],
        ys: &[f64],
        radius: f32,
        color: Rgba,
    ) -> Result<(), CanvasError> {
        same_length(xs, ys)?;
        check_positive("a marker radius", radius)?;
        let (w, h) = self.size();
        let [cx0, cy0, cx1, cy1] = match &self.clip {
            Some((k, _)) => *k,
            None => [0, 0, w as i32, h as i32],
        };
        let (lo_x, lo_y) = (cx0.max(0), cy0.max(0));
        let (hi_x, hi_y) = (cx1.min(w as i32), cy1.min(h as i32));
        let alpha = f32::from(color[3]) / 255.0;
        let src = [color[0], color[1], color[2]].map(|c| f32::from(c) * alpha);
        let reach = radius + 0.5;
        let data = self.pixmap.data_mut();
        for (&x, &y) in xs.iter().zip(ys) {
            if !(x.is_finite() && y.is_finite()) {
                continue;
            }
            let (x, y) = (x as f32, y as f32);
            let px0 = ((x - reach).floor() as i32).max(lo_x);
            let px1 = ((x + reach).ceil() as i32).min(hi_x);
            let py0 = ((y - reach).floor() as i32).max(lo_y);
            let py1 = ((y + reach).ceil() as i32).min(hi_y);
            for py in py0..py1 {
                let dy = py as f32 + 0.5 - y;
                for px in px0..px1 {
                    let dx = px as f32 + 0.5 - x;
                    let cover = (reach - (dx * dx + dy * dy).sqrt()).clamp(0.0, 1.0);
                    if cover <= 0.0 {
                        continue;
                    }
                    // Source over, premultiplied RGBA bytes.
                    let a = alpha * cover;
                    let at = 4 * (py as usize * w as usize + px as usize);
                    let pixel = &mut data[at..at + 4];
                    for (d, s) in pixel[..3].iter_mut().zip(src) {
                        *d = (s * cover + f32::from(*d) * (1.0 - a)).round().min(255.0) as u8;
                    }
                    pixel[3] = (255.0 * a + f32::from(pixel[3]) * (1.0 - a))
                        .round()
                        .min(255.0) as u8;
                }
            }
        }
        Ok(())
    }

    fn scale(&self, size: f32) -> f32 {
        // Size is the em height in pixels, as a font size in points is at 72 dpi.
        size / self.font.units_per_em().unwrap_or(2048.0)
    }

    /// The width and the ascender and descender of `text` at `size` pixels per em.
    pub fn text_extent(&self, text: &str, size: f32) -> TextExtent {
        let s = self.scale(size);
        let mut width = 0.0;
        let mut prev: Option<GlyphId> = None;
        for c in text.chars() {
            let id = self.font.glyph_id(c);
            if let Some(p) = prev {
                width += self.font.kern_unscaled(p, id) * s;
            }
            width += self.font.h_advance_unscaled(id) * s;
            prev = Some(id);
        }
        TextExtent {
            width,
            ascent: self.font.ascent_unscaled() * s,
            descent: -self.font.descent_unscaled() * s,
        }
    }

    fn glyph_path(&mut self, id: GlyphId) -> Option<Path> {
        if let Some(p) = self.glyphs.get(&id) {
            return p.clone();
        }
        let path = self.font.outline(id).and_then(|outline| {
            let mut pb = PathBuilder::new();
            let mut end: Option<(f32, f32)> = None;
            for curve in &outline.curves {
                let (start, last) = match curve {
                    OutlineCurve::Line(a, b) => ((a.x, a.y), (b.x, b.y)),
                    OutlineCurve::Quad(a, _, c) => ((a.x, a.y), (c.x, c.y)),
                    OutlineCurve::Cubic(a, _, _, d) => ((a.x, a.y), (d.x, d.y)),
                };
                if end != Some(start) {
                    if end.is_some() {
                        pb.close();
                    }
                    pb.move_to(start.0, start.1);
                }
                match curve {
                    OutlineCurve::Line(_, b) => pb.line_to(b.x, b.y),
                    OutlineCurve::Quad(_, b, c) => pb.quad_to(b.x, b.y, c.x, c.y),
                    OutlineCurve::Cubic(_, b, c, d) => pb.cubic_to(b.x, b.y, c.x, c.y, d.x, d.y),
                }
                end = Some(last);
            }
            if end.is_some() {
                pb.close();
            }
            pb.finish()
        });
        self.glyphs.insert(id, path.clone());
        path
    }

    /// Draws `text` at `size` pixels per em with its anchor (`ha`, `va`) at (x, y),
    /// rotated by `rotation` degrees counter-clockwise about that point. Characters the
    /// font lacks are drawn as its missing-glyph box. Not clipped.
    #[allow(clippy::too_many_arguments)]
    pub fn text(
        &mut self,
        text: &str,
        x: f32,
        y: f32,
        size: f32,
        ha: HAlign,
        va: VAlign,
        rotation: f32,
        color: Rgba,
    ) -> Result<(), CanvasError> {
        check_positive("a font size", size)?;
        if !(x.is_finite() && y.is_finite() && rotation.is_finite()) {
            return Ok(());
        }
        let ext = self.text_extent(text, size);
        let dx = match ha {
            HAlign::Left => 0.0,
            HAlign::Center => -ext.width / 2.0,
            HAlign::Right => -ext.width,
        };
        // Offset of the baseline below the anchor, in the text's own (unrotated) frame.
        let dy = match va {
            VAlign::Top => ext.ascent,
            VAlign::Center => (ext.ascent - ext.descent) / 2.0,
            VAlign::Baseline => 0.0,
            VAlign::Bottom => -ext.descent,
        };
        let s = self.scale(size);
        let (sin, cos) = rotation.to_radians().sin_cos();
        let p = paint(color);
        let mut pen = dx;
        let mut prev: Option<GlyphId> = None;
        for c in text.chars() {
            let id = self.font.glyph_id(c);
            if let Some(q) = prev {
                pen += self.font.kern_unscaled(q, id) * s;
            }
            prev = Some(id);
            if let Some(path) = self.glyph_path(id) {
                // Font units (y up) → the text's frame (x along the baseline, y down) →
                // the image, rotated about (x, y).
                let tx = x + cos * pen + sin * dy;
                let ty = y - sin * pen + cos * dy;
                let t = Transform::from_row(cos * s, -sin * s, -sin * s, -cos * s, tx, ty);
                self.pixmap.fill_path(&path, &p, FillRule::Winding, t, None);
            }
            pen += self.font.h_advance_unscaled(id) * s;
        }
        Ok(())
    }

    /// The image as PNG bytes (8-bit RGB; fast compression: flat plots compress well).
    pub fn png(&self) -> Result<Vec<u8>, CanvasError> {
        let (w, h) = self.size();
        // Opaque everywhere (a white start, source-over drawing): premultiplied RGBA is
        // plain RGBA, and the alpha channel is dropped.
        let rgb: Vec<u8> = self
            .pixmap
            .data()
            .chunks_exact(4)
            .flat_map(|px| [px[0], px[1], px[2]])
            .collect();
        let mut out = Vec::with_capacity(rgb.len() / 8);
        {
            let mut enc = png::Encoder::new(&mut out, w, h);
            enc.set_color(png::ColorType::Rgb);
            enc.set_depth(png::BitDepth::Eight);
            enc.set_compression(png::Compression::Fast);
            enc.set_filter(png::FilterType::Sub);
            let mut writer = enc
                .write_header()
                .map_err(|e| CanvasError::Encode(e.to_string()))?;
            writer
                .write_image_data(&rgb)
                .map_err(|e| CanvasError::Encode(e.to_string()))?;
        }
        Ok(out)
    }

    /// The pixel at (x, y) as RGBA (premultiplied, i.e. plain where opaque), for tests.
    pub fn pixel(&self, x: u32, y: u32) -> Option<Rgba> {
        self.pixmap.pixel(x, y).map(|c| {
            let c = c.demultiply();
            [c.red(), c.green(), c.blue(), c.alpha()]
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const BLACK: Rgba = [0, 0, 0, 255];

    #[test]
    fn a_new_canvas_is_white_and_bad_sizes_are_refused() {
        let c = Canvas::new(10, 5).unwrap();
        assert_eq!(c.pixel(9, 4), Some([255, 255, 255, 255]));
        assert!(matches!(Canvas::new(0, 5), Err(CanvasError::Size { .. })));
        assert!(matches!(
            Canvas::new(MAX_SIDE + 1, 5),
            Err(CanvasError::Size { .. })
        ));
    }

    #[test]
    fn a_line_colours_the_pixels_it_crosses_and_a_nan_breaks_it() {
        let mut c = Canvas::new(40, 20).unwrap();
        let xs = [2.0, 18.0, f64::NAN, 22.0, 38.0];
        let ys = [10.5, 10.5, 10.5, 10.5, 10.5];
        c.polyline(&xs, &ys, BLACK, 1.0, &[]).unwrap();
        assert_eq!(c.pixel(10, 10), Some(BLACK));
        assert_eq!(c.pixel(30, 10), Some(BLACK));
        assert_eq!(c.pixel(20, 10), Some([255, 255, 255, 255])); // the gap
        assert_eq!(c.pixel(10, 5), Some([255, 255, 255, 255]));
        assert!(matches!(
            c.polyline(&xs, &ys[..2], BLACK, 1.0, &[]),
            Err(CanvasError::Lengths { .. })
        ));
        assert!(c.polyline(&xs, &ys, BLACK, 0.0, &[]).is_err());
    }

    #[test]
    fn the_clip_keeps_shapes_inside_it() {
        let mut c = Canvas::new(20, 20).unwrap();
        c.set_clip(Some([0.0, 0.0, 10.0, 20.0]));
        c.fill_rect([0.0, 0.0, 20.0, 20.0], BLACK);
        c.set_clip(None);
        assert_eq!(c.pixel(5, 5), Some(BLACK));
        assert_eq!(c.pixel(15, 5), Some([255, 255, 255, 255]));
    }

    #[test]
    fn text_is_as_wide_as_its_advances_and_rotates() {
        let mut c = Canvas::new(200, 200).unwrap();
        let one = c.text_extent("m", 20.0).width;
        let three = c.text_extent("mmm", 20.0).width;
        assert!(
            one > 5.0 && (three - 3.0 * one).abs() < 1e-3,
            "{one} {three}"
        );
        let e = c.text_extent("Ag", 20.0);
        assert!(e.ascent > 10.0 && e.descent > 2.0, "{e:?}");
        // Rotated by 90°, a text's ink runs up from its anchor, not right.
        c.text(
            "mmmmm",
            100.0,
            100.0,
            20.0,
            HAlign::Left,
            VAlign::Baseline,
            90.0,
            BLACK,
        )
        .unwrap();
        let ink = |x0: u32, x1: u32, y0: u32, y1: u32| {
            (x0..x1)
                .flat_map(|x| (y0..y1).map(move |y| (x, y)))
                .filter(|&(x, y)| c.pixel(x, y).unwrap()[0] < 128)
                .count()
        };
        assert!(ink(85, 100, 45, 100) > 50);
        assert_eq!(ink(101, 200, 0, 200), 0);
        assert_eq!(ink(0, 200, 101, 200), 0);
    }

    #[test]
    fn a_marker_inks_its_disc_and_overlaps_darken() {
        let mut c = Canvas::new(40, 20).unwrap();
        let blue: Rgba = [0, 0, 255, 102];
        c.markers(&[10.5], &[10.5], 3.0, blue).unwrap();
        // Ink (coverage) summed over the pixels ≈ the disc's area π·r².
        let ink: f32 = (0..40)
            .flat_map(|x| (0..20).map(move |y| (x, y)))
            .map(|(x, y)| (255.0 - f32::from(c.pixel(x, y).unwrap()[0])) / 102.0)
            .sum();
        let area = std::f32::consts::PI * 9.0;
        assert!((ink - area).abs() < 0.05 * area, "{ink} vs {area}");
        assert_eq!(c.pixel(10, 14).map(|p| p[0]), Some(255)); // outside r + ½
        let once = c.pixel(10, 10).unwrap();
        c.markers(&[10.5], &[10.5], 3.0, blue).unwrap();
        let twice = c.pixel(10, 10).unwrap();
        assert!(twice[0] < once[0], "{once:?} {twice:?}");
        // Clipped: nothing right of x = 20.
        c.set_clip(Some([0.0, 0.0, 20.0, 20.0]));
        c.markers(&[20.0], &[10.5], 3.0, [0, 0, 0, 255]).unwrap();
        assert_eq!(c.pixel(19, 10).unwrap()[0], 0);
        assert_eq!(c.pixel(20, 10).unwrap()[0], 255);
    }

    #[test]
    fn the_png_has_the_canvas_size_and_pixels() {
        let mut c = Canvas::new(7, 3).unwrap();
        c.fill_rect([0.0, 0.0, 7.0, 3.0], [10, 20, 30, 255]);
        let bytes = c.png().unwrap();
        let dec = png::Decoder::new(&bytes[..]);
        let mut reader = dec.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!((info.width, info.height), (7, 3));
        assert_eq!(&buf[..3], &[10, 20, 30]);
    }
}
