//! `prrrp._prrrp.Canvas`: the raster canvas of `prrrp-figures` (the report figures of
//! `prrrp identify` without matplotlib; laid out by python/prrrp/canvas.py).

use prrrp_figures::{Canvas as Inner, CanvasError, HAlign, Rgba, VAlign};
use pyo3::prelude::*;
use pyo3::types::PyBytes;

use crate::arrays::vector;
use crate::errors::{Exc, ToPyResult};

impl<T> ToPyResult<T> for Result<T, CanvasError> {
    /// A canvas error is the caller's input (a size, a width, unequal lengths).
    fn to_py(self, py: Python<'_>) -> PyResult<T> {
        self.map_err(|e| Exc::InvalidInput.new_err(py, e.to_string(), &[]))
    }
}

fn halign(py: Python<'_>, ha: &str) -> PyResult<HAlign> {
    match ha {
        "left" => Ok(HAlign::Left),
        "center" => Ok(HAlign::Center),
        "right" => Ok(HAlign::Right),
        _ => Err(Exc::InvalidInput.new_err(
            py,
            format!("ha must be left, center or right, got {ha:?}"),
            &[],
        )),
    }
}

fn valign(py: Python<'_>, va: &str) -> PyResult<VAlign> {
    match va {
        "top" => Ok(VAlign::Top),
        "center" => Ok(VAlign::Center),
        "baseline" => Ok(VAlign::Baseline),
        "bottom" => Ok(VAlign::Bottom),
        _ => Err(Exc::InvalidInput.new_err(
            py,
            format!("va must be top, center, baseline or bottom, got {va:?}"),
            &[],
        )),
    }
}

/// A white RGBA image of `width` × `height` pixels to draw on, in pixel coordinates (x
/// right, y down from the top-left corner); colours are (r, g, b, a) of 0..255.
#[pyclass(name = "Canvas", module = "prrrp._prrrp")]
pub(crate) struct Canvas(Inner);

/// The `#[pymethods]` of `Canvas`: its own items, then one method per shape drawn through
/// points, `fn name(args) = |c, xs, ys| draw;`, taking the (N,) coordinate arrays `xs`,
/// `ys` and then `args`, with `draw` drawing on the canvas `c` at the points read.
macro_rules! canvas_pymethods {
    ({ $($own:tt)* }
     $($(#[$doc:meta])* fn $name:ident($($arg:ident: $ty:ty),*) = |$c:ident, $xs:ident, $ys:ident| $draw:expr;)*) => {
        #[pymethods]
        impl Canvas {
            $($own)*
            $(
            $(#[$doc])*
            fn $name(
                &mut self,
                py: Python<'_>,
                xs: &Bound<'_, PyAny>,
                ys: &Bound<'_, PyAny>,
                $($arg: $ty),*
            ) -> PyResult<()> {
                let ($xs, $ys) = (vector(xs, "xs")?, vector(ys, "ys")?);
                let $c = &mut self.0;
                $draw.to_py(py)
            }
            )*
        }
    };
}

canvas_pymethods! {{
    #[new]
    fn new(py: Python<'_>, width: u32, height: u32) -> PyResult<Self> {
        Inner::new(width, height).map(Self).to_py(py)
    }

    /// (width, height), pixels.
    #[getter]
    fn size(&self) -> (u32, u32) {
        self.0.size()
    }

    /// Shapes drawn next stay inside the rectangle (x0, y0, x1, y1); None lifts it.
    #[pyo3(signature = (rect))]
    fn set_clip(&mut self, rect: Option<(f32, f32, f32, f32)>) {
        self.0.set_clip(rect.map(|(a, b, c, d)| [a, b, c, d]));
    }

    /// A filled rectangle between the corners (x0, y0) and (x1, y1).
    fn fill_rect(&mut self, x0: f32, y0: f32, x1: f32, y1: f32, color: Rgba) {
        self.0.fill_rect([x0, y0, x1, y1], color);
    }

    /// A rectangle's outline, `width` pixels wide.
    #[allow(clippy::too_many_arguments)]
    fn stroke_rect(
        &mut self,
        py: Python<'_>,
        x0: f32,
        y0: f32,
        x1: f32,
        y1: f32,
        color: Rgba,
        width: f32,
    ) -> PyResult<()> {
        self.0.stroke_rect([x0, y0, x1, y1], color, width).to_py(py)
    }

    /// `text` at `size` pixels per em, anchored (`ha`: left/center/right, `va`:
    /// top/center/baseline/bottom) at (x, y), rotated `rotation` degrees
    /// counter-clockwise.
    #[allow(clippy::too_many_arguments)]
    #[pyo3(signature = (text, x, y, size, ha = "left", va = "baseline", rotation = 0.0, color = (0, 0, 0, 255)))]
    fn text(
        &mut self,
        py: Python<'_>,
        text: &str,
        x: f32,
        y: f32,
        size: f32,
        ha: &str,
        va: &str,
        rotation: f32,
        color: (u8, u8, u8, u8),
    ) -> PyResult<()> {
        let (ha, va) = (halign(py, ha)?, valign(py, va)?);
        let c = [color.0, color.1, color.2, color.3];
        self.0.text(text, x, y, size, ha, va, rotation, c).to_py(py)
    }

    /// (width, ascent, descent) of `text` at `size` pixels per em, pixels.
    fn text_extent(&self, text: &str, size: f32) -> (f32, f32, f32) {
        let e = self.0.text_extent(text, size);
        (e.width, e.ascent, e.descent)
    }

    /// The image as PNG bytes.
    fn png<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyBytes>> {
        let bytes = py.detach(|| self.0.png()).to_py(py)?;
        Ok(PyBytes::new(py, &bytes))
    }
}

    /// A line through (xs[i], ys[i]), `width` pixels wide; `dash` = on/off lengths
    /// (pixels; empty: solid). NaN breaks the line.
    #[pyo3(signature = (xs, ys, color, width, dash = Vec::new()))]
    fn polyline(color: Rgba, width: f32, dash: Vec<f32>) =
        |c, xs, ys| c.polyline(&xs, &ys, color, width, &dash);

    /// The closed polygon through (xs[i], ys[i]), filled.
    fn fill_polygon(color: Rgba) = |c, xs, ys| c.fill_polygon(&xs, &ys, color);

    /// A filled disc of `radius` pixels at each (xs[i], ys[i]).
    fn markers(radius: f32, color: Rgba) = |c, xs, ys| c.markers(&xs, &ys, radius, color);
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Canvas>()?;
    Ok(())
}
