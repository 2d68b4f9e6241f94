//! SVG line charts for curves people would rather look at than read.
//!
//! Pure SVG through plotters' SVG backend without system fonts, so plots work
//! on a fresh machine with no fontconfig.

use std::path::Path;

use plotters::coord::ranged1d::ValueFormatter;
use plotters::prelude::*;

use crate::error::{IoError, Result};

/// Line style of a series.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LineStyle {
    /// Solid line.
    Solid,
    /// Dashed line (bounds, references).
    Dashed,
    /// Unconnected markers (events such as anomalous fixes).
    Points,
}

/// One curve.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend label.
    pub label: String,
    /// (x, y) points; non-finite y values break the line.
    pub points: Vec<(f64, f64)>,
    /// Style.
    pub style: LineStyle,
    /// Palette index (same index, same colour).
    pub color: usize,
}

/// A chart with a title, axis labels and curves.
#[derive(Debug, Clone)]
pub struct LineChart {
    /// Title on top.
    pub title: String,
    /// X axis label (with unit).
    pub x_label: String,
    /// Y axis label (with unit).
    pub y_label: String,
    /// Curves.
    pub series: Vec<Series>,
    /// Logarithmic y axis.
    pub log_y: bool,
}

/// Colours by index; the last one (black) is [`TRUTH_COLOR`].
const PALETTE: [RGBColor; 9] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(23, 190, 207),
    RGBColor(188, 189, 34),
    RGBColor(0, 0, 0),
];

/// Palette index of black, for truth curves and references.
pub const TRUTH_COLOR: usize = 8;

impl LineChart {
    /// Render to an SVG file at `path` (800×500 px), atomically (under a
    /// temporary name, then renamed).
    pub fn write_svg(&self, path: &Path) -> Result<()> {
        let staged = crate::writers::Staged::new(path);
        self.render_svg(staged.tmp(), path, false)?;
        staged.commit().map(|_| ())
    }

    /// [`write_svg`](Self::write_svg) with a logarithmic x axis too (and a
    /// logarithmic y axis whatever `log_y` says): an Allan deviation, a
    /// spectrum. Points with x ≤ 0 or y ≤ 0 are left out.
    pub fn write_svg_log_log(&self, path: &Path) -> Result<()> {
        let staged = crate::writers::Staged::new(path);
        let chart = LineChart {
            log_y: true,
            ..self.clone()
        };
        chart.render_svg(staged.tmp(), path, true)?;
        staged.commit().map(|_| ())
    }

    fn render_svg(&self, tmp: &Path, path: &Path, log_x: bool) -> Result<()> {
        let err = |e: String| IoError::Write {
            path: path.to_path_buf(),
            message: e,
        };
        let finite = self
            .series
            .iter()
            .flat_map(|s| s.points.iter())
            .filter(|(x, y)| {
                x.is_finite() && y.is_finite() && (!self.log_y || *y > 0.0) && (!log_x || *x > 0.0)
            });
        let (mut x0, mut x1, mut y0, mut y1) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        for &(x, y) in finite {
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
        }
        if !x0.is_finite() {
            (x0, x1, y0, y1) = (
                if log_x { 0.1 } else { 0.0 },
                1.0,
                if self.log_y { 0.1 } else { 0.0 },
                1.0,
            );
        }
        if x1 <= x0 {
            x1 = x0 + x0.abs().max(1.0);
        }
        if y1 <= y0 {
            y1 = y0 + y0.abs().max(1.0) * 0.1;
        }
        let root = SVGBackend::new(tmp, (800, 500)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        let mut builder = ChartBuilder::on(&root);
        builder
            .caption(&self.title, ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70);
        if log_x {
            let mut chart = builder
                .build_cartesian_2d((x0..x1).log_scale(), (y0..y1 * 1.05).log_scale())
                .map_err(|e| err(e.to_string()))?;
            self.draw_into(&mut chart, true).map_err(err)?;
        } else if self.log_y {
            let mut chart = builder
                .build_cartesian_2d(x0..x1, (y0..y1 * 1.05).log_scale())
                .map_err(|e| err(e.to_string()))?;
            self.draw_into(&mut chart, false).map_err(err)?;
        } else {
            let pad = 0.05 * (y1 - y0);
            let mut chart = builder
                .build_cartesian_2d(x0..x1, (y0 - pad)..(y1 + pad))
                .map_err(|e| err(e.to_string()))?;
            self.draw_into(&mut chart, false).map_err(err)?;
        }
        root.present().map_err(|e| err(e.to_string()))
    }

    /// Mesh, curves and legend, whatever the y axis.
    fn draw_into<'a, X, Y>(
        &self,
        chart: &mut ChartContext<'a, SVGBackend<'a>, Cartesian2d<X, Y>>,
        log_x: bool,
    ) -> std::result::Result<(), String>
    where
        X: Ranged<ValueType = f64> + ValueFormatter<f64>,
        Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
    {
        chart
            .configure_mesh()
            .x_desc(&self.x_label)
            .y_desc(&self.y_label)
            .draw()
            .map_err(|e| e.to_string())?;
        self.draw_series(chart, log_x)?;
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| e.to_string())
    }

    fn draw_series<'a, X, Y>(
        &self,
        chart: &mut ChartContext<'a, SVGBackend<'a>, Cartesian2d<X, Y>>,
        log_x: bool,
    ) -> std::result::Result<(), String>
    where
        X: Ranged<ValueType = f64>,
        Y: Ranged<ValueType = f64>,
    {
        for s in &self.series {
            let color = PALETTE[s.color % PALETTE.len()];
            let style = ShapeStyle::from(&color).stroke_width(2);
            // Split at non-finite points so gaps stay gaps.
            let mut segments: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
            for &(x, y) in &s.points {
                if x.is_finite() && y.is_finite() && (!self.log_y || y > 0.0) && (!log_x || x > 0.0)
                {
                    if let Some(v) = segments.last_mut() {
                        v.push((x, y));
                    }
                } else if segments.last().is_some_and(|v| !v.is_empty()) {
                    segments.push(Vec::new());
                }
            }
            let mut first = true;
            for seg in segments.into_iter().filter(|v| !v.is_empty()) {
                let anno = match s.style {
                    LineStyle::Solid => chart.draw_series(LineSeries::new(seg, style)),
                    LineStyle::Dashed => chart.draw_series(DashedLineSeries::new(seg, 8, 5, style)),
                    LineStyle::Points => chart
                        .draw_series(seg.into_iter().map(|p| Circle::new(p, 2, color.filled()))),
                }
                .map_err(|e| e.to_string())?;
                if first {
                    anno.label(s.label.clone()).legend(move |(x, y)| {
                        PathElement::new(
                            vec![(x, y), (x + 20, y)],
                            ShapeStyle::from(&color).stroke_width(2),
                        )
                    });
                    first = false;
                }
            }
        }
        Ok(())
    }
}
