//! Plots for the experiment runner and the statistics suite, written with plotters as
//! PNG and SVG side by side. Text uses the DejaVu Sans font bundled in `assets/`
//! (registered once), so plots look the same on every machine.

use anyhow::{Context, Result, anyhow};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::Once;

static FONT: Once = Once::new();

fn ensure_font() {
    FONT.call_once(|| {
        // The bytes are a valid TrueType font shipped with the crate.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, include_bytes!("../assets/DejaVuSans.ttf"));
    });
}

/// One named line of points.
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend label.
    pub name: String,
    /// (x, y) points, drawn in the given order.
    pub points: Vec<(f64, f64)>,
}

/// A line chart.
#[derive(Clone, Debug)]
pub struct LinePlot {
    /// Title.
    pub title: String,
    /// X-axis label (with unit).
    pub x_label: String,
    /// Y-axis label (with unit).
    pub y_label: String,
    /// Logarithmic x axis.
    pub log_x: bool,
    /// Logarithmic y axis.
    pub log_y: bool,
    /// Lines.
    pub series: Vec<Series>,
}

/// A horizontal band across a line chart, from `lo` (clipped to the bottom of the
/// axis) to `hi`, drawn translucent under the lines with a line along its top: a
/// level the data cannot resolve beyond (a reference's own noise).
#[derive(Clone, Debug)]
pub struct Band {
    /// Legend label.
    pub name: String,
    /// Bottom (0, or anything below the axis, fills to the bottom).
    pub lo: f64,
    /// Top.
    pub hi: f64,
}

/// Stacked bars: one bar per category, one layer per stack entry.
#[derive(Clone, Debug)]
pub struct StackedBars {
    /// Title.
    pub title: String,
    /// Y-axis label (with unit).
    pub y_label: String,
    /// Bar labels.
    pub categories: Vec<String>,
    /// (layer name, value per category).
    pub layers: Vec<(String, Vec<f64>)>,
}

fn range(vals: impl Iterator<Item = f64>, log: bool) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in vals.filter(|v| v.is_finite() && (!log || *v > 0.0)) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return if log { (0.1, 10.0) } else { (0.0, 1.0) };
    }
    if log {
        if hi <= lo {
            (lo / 2.0, hi * 2.0)
        } else {
            let f = (hi / lo).powf(0.05);
            (lo / f, hi * f)
        }
    } else if hi <= lo {
        (lo - 1.0, hi + 1.0)
    } else {
        let pad = 0.05 * (hi - lo);
        (lo - pad, hi + pad)
    }
}

fn draw_lines<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, p: &LinePlot, bands: &[Band]) -> Result<()>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(|e| anyhow!("{e:?}"))?;
    let (x0, x1) = range(p.series.iter().flat_map(|s| s.points.iter().map(|q| q.0)), p.log_x);
    // The y range takes in each band's top, so a floor below every point still shows.
    let band_tops = bands.iter().map(|b| b.hi);
    let (y0, y1) = range(p.series.iter().flat_map(|s| s.points.iter().map(|q| q.1)).chain(band_tops), p.log_y);
    let mut b = ChartBuilder::on(&root);
    b.caption(&p.title, ("sans-serif", 22)).margin(12).x_label_area_size(45).y_label_area_size(70);
    macro_rules! body {
        ($chart:expr) => {{
            let mut chart = $chart;
            chart
                .configure_mesh()
                .x_desc(p.x_label.as_str())
                .y_desc(p.y_label.as_str())
                .label_style(("sans-serif", 14))
                .draw()
                .map_err(|e| anyhow!("{e:?}"))?;
            // Bands first, so the lines are drawn over them; greys apart from the lines' colours.
            for (i, band) in bands.iter().enumerate().filter(|(_, b)| b.hi.is_finite() && b.hi > y0) {
                let shade = RGBColor(90 + (i as u8 % 4) * 30, 90 + (i as u8 % 4) * 30, 110 + (i as u8 % 4) * 30);
                let (lo, hi) = (band.lo.max(y0), band.hi.min(y1));
                chart
                    .draw_series(std::iter::once(Rectangle::new([(x0, lo), (x1, hi)], shade.mix(0.18).filled())))
                    .map_err(|e| anyhow!("{e:?}"))?
                    .label(band.name.as_str())
                    .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 20, y + 5)], shade.mix(0.35).filled()));
                chart
                    .draw_series(std::iter::once(PathElement::new(vec![(x0, hi), (x1, hi)], shade.stroke_width(1))))
                    .map_err(|e| anyhow!("{e:?}"))?;
            }
            for (i, s) in p.series.iter().enumerate() {
                let color = Palette99::pick(i).to_rgba();
                let pts: Vec<(f64, f64)> = s
                    .points
                    .iter()
                    .copied()
                    .filter(|&(x, y)| x.is_finite() && y.is_finite() && (!p.log_x || x > 0.0) && (!p.log_y || y > 0.0))
                    .collect();
                chart
                    .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))
                    .map_err(|e| anyhow!("{e:?}"))?
                    .label(s.name.as_str())
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
                chart.draw_series(pts.into_iter().map(|q| Circle::new(q, 3, color.filled()))).map_err(|e| anyhow!("{e:?}"))?;
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font(("sans-serif", 13))
                .position(legend_corner(p, bands, (x0, x1), (y0, y1)))
                .draw()
                .map_err(|e| anyhow!("{e:?}"))?;
        }};
    }
    match (p.log_x, p.log_y) {
        (true, true) => body!(b.build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale()).map_err(|e| anyhow!("{e:?}"))?),
        (true, false) => body!(b.build_cartesian_2d((x0..x1).log_scale(), y0..y1).map_err(|e| anyhow!("{e:?}"))?),
        (false, true) => body!(b.build_cartesian_2d(x0..x1, (y0..y1).log_scale()).map_err(|e| anyhow!("{e:?}"))?),
        (false, false) => body!(b.build_cartesian_2d(x0..x1, y0..y1).map_err(|e| anyhow!("{e:?}"))?),
    }
    root.present().map_err(|e| anyhow!("{e:?}"))?;
    Ok(())
}

/// The corner of the plot area whose legend box would cover the fewest points of the
/// lines (segments sampled too), the upper right on a tie.
fn legend_corner(p: &LinePlot, bands: &[Band], (x0, x1): (f64, f64), (y0, y1): (f64, f64)) -> SeriesLabelPosition {
    let unit = |v: f64, lo: f64, hi: f64, log: bool| if log { (v.ln() - lo.ln()) / (hi.ln() - lo.ln()) } else { (v - lo) / (hi - lo) };
    // The box: the longest label's width at ~7 px a character over a ~800-px plot,
    // 20 px an entry over a ~480-px plot, in units of the plot area.
    let names = p.series.iter().map(|s| &s.name).chain(bands.iter().map(|b| &b.name));
    let longest = names.map(|n| n.chars().count()).max().unwrap_or(0) + 8;
    let (w, h) = ((longest as f64 * 7.0 / 800.0).min(0.9), (((p.series.len() + bands.len()) as f64 * 20.0 + 10.0) / 480.0).min(0.9));
    let mut pts = Vec::new();
    for s in &p.series {
        let q: Vec<(f64, f64)> = s
            .points
            .iter()
            .filter(|&&(x, y)| x.is_finite() && y.is_finite() && (!p.log_x || x > 0.0) && (!p.log_y || y > 0.0))
            .map(|&(x, y)| (unit(x, x0, x1, p.log_x), unit(y, y0, y1, p.log_y)))
            .collect();
        for (i, &a) in q.iter().enumerate() {
            pts.push(a);
            if let Some(&b) = q.get(i + 1) {
                pts.extend((1..8).map(|k| (a.0 + (b.0 - a.0) * k as f64 / 8.0, a.1 + (b.1 - a.1) * k as f64 / 8.0)));
            }
        }
    }
    let corners = [
        (SeriesLabelPosition::UpperRight, (1.0 - w, 1.0), (1.0 - h, 1.0)),
        (SeriesLabelPosition::UpperLeft, (0.0, w), (1.0 - h, 1.0)),
        (SeriesLabelPosition::LowerLeft, (0.0, w), (0.0, h)),
        (SeriesLabelPosition::LowerRight, (1.0 - w, 1.0), (0.0, h)),
    ];
    let covered = |(_, (ua, ub), (va, vb)): &(SeriesLabelPosition, (f64, f64), (f64, f64))| {
        pts.iter().filter(|&&(u, v)| u >= *ua && u <= *ub && v >= *va && v <= *vb).count()
    };
    let mut best = 0;
    for (i, c) in corners.iter().enumerate() {
        if covered(c) < covered(&corners[best]) {
            best = i;
        }
    }
    corners[best].0.clone()
}

fn draw_bars<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, p: &StackedBars) -> Result<()>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(|e| anyhow!("{e:?}"))?;
    let n = p.categories.len().max(1);
    let ymax = (0..n).map(|i| p.layers.iter().map(|l| l.1.get(i).copied().unwrap_or(0.0).max(0.0)).sum::<f64>()).fold(0.0f64, f64::max);
    let ymax = if ymax > 0.0 && ymax.is_finite() { ymax * 1.1 } else { 1.0 };
    let cats = p.categories.clone();
    let mut chart = ChartBuilder::on(&root)
        .caption(&p.title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(60)
        .y_label_area_size(80)
        .build_cartesian_2d(-0.5f64..n as f64 - 0.5, 0f64..ymax)
        .map_err(|e| anyhow!("{e:?}"))?;
    chart
        .configure_mesh()
        .disable_x_mesh()
        .x_labels(n)
        // Bar i is centred on x = i, so the integer ticks carry the category names.
        .x_label_formatter(&|x| {
            if (x - x.round()).abs() < 1e-9 && *x >= -0.1 {
                cats.get(x.round() as usize).cloned().unwrap_or_default()
            } else {
                String::new()
            }
        })
        .y_desc(p.y_label.as_str())
        .label_style(("sans-serif", 13))
        .draw()
        .map_err(|e| anyhow!("{e:?}"))?;
    let mut base = vec![0.0f64; n];
    for (li, (name, vals)) in p.layers.iter().enumerate() {
        let color = Palette99::pick(li).to_rgba();
        let rects: Vec<Rectangle<(f64, f64)>> = (0..n)
            .map(|i| {
                let v = vals.get(i).copied().unwrap_or(0.0).max(0.0);
                let r = Rectangle::new([(i as f64 - 0.35, base[i]), (i as f64 + 0.35, base[i] + v)], color.filled());
                base[i] += v;
                r
            })
            .collect();
        chart
            .draw_series(rects)
            .map_err(|e| anyhow!("{e:?}"))?
            .label(name.as_str())
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 12, y + 5)], color.filled()));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 13))
        .draw()
        .map_err(|e| anyhow!("{e:?}"))?;
    root.present().map_err(|e| anyhow!("{e:?}"))?;
    Ok(())
}

fn both(stem: &Path, png: impl FnOnce(&Path) -> Result<()>, svg: impl FnOnce(&Path) -> Result<()>) -> Result<(PathBuf, PathBuf)> {
    ensure_font();
    if let Some(d) = stem.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(d).with_context(|| format!("{}: cannot create directory", d.display()))?;
    }
    let (p, s) = (stem.with_extension("png"), stem.with_extension("svg"));
    let (tp, ts) = (crate::film::temp_path(&p).with_extension("png"), crate::film::temp_path(&s).with_extension("svg"));
    png(&tp).with_context(|| format!("{}: cannot draw plot", p.display()))?;
    svg(&ts).with_context(|| format!("{}: cannot draw plot", s.display()))?;
    std::fs::rename(&tp, &p).with_context(|| format!("{}: cannot rename into place", p.display()))?;
    std::fs::rename(&ts, &s).with_context(|| format!("{}: cannot rename into place", s.display()))?;
    Ok((p, s))
}

/// Size of every plot, in pixels (PNG) and user units (SVG).
const PLOT_SIZE: (u32, u32) = (900, 600);

/// Draws into an RGB buffer and writes it as a PNG with the film's encoder (plotters' own
/// encoder would build the `image` crate into the binary).
fn png_file(path: &Path, draw: impl FnOnce(DrawingArea<BitMapBackend<'_>, Shift>) -> Result<()>) -> Result<()> {
    let (w, h) = PLOT_SIZE;
    let mut buf = vec![0u8; (w * h * 3) as usize];
    draw(BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area())?;
    let png = crate::film::encode_png_rgb8(w, h, &buf)?;
    std::fs::write(path, png).with_context(|| format!("{}: cannot write PNG", path.display()))
}

/// Writes `stem.png` and `stem.svg` with a line chart.
pub fn line_plot(stem: &Path, plot: &LinePlot) -> Result<(PathBuf, PathBuf)> {
    line_plot_with_bands(stem, plot, &[])
}

/// [`line_plot`] with horizontal bands under the lines.
pub fn line_plot_with_bands(stem: &Path, plot: &LinePlot, bands: &[Band]) -> Result<(PathBuf, PathBuf)> {
    both(
        stem,
        |p| png_file(p, |b| draw_lines(b, plot, bands)),
        |p| draw_lines(SVGBackend::new(p, PLOT_SIZE).into_drawing_area(), plot, bands),
    )
}

/// Writes `stem.png` and `stem.svg` with stacked bars.
pub fn bar_plot(stem: &Path, plot: &StackedBars) -> Result<(PathBuf, PathBuf)> {
    both(stem, |p| png_file(p, |b| draw_bars(b, plot)), |p| draw_bars(SVGBackend::new(p, PLOT_SIZE).into_drawing_area(), plot))
}

/// Least-squares slope of log(y) against log(x) over the points with x, y > 0.
pub fn log_log_slope(points: &[(f64, f64)]) -> Option<f64> {
    let pts: Vec<(f64, f64)> = points.iter().filter(|p| p.0 > 0.0 && p.1 > 0.0).map(|p| (p.0.ln(), p.1.ln())).collect();
    if pts.len() < 2 {
        return None;
    }
    let n = pts.len() as f64;
    let mx = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx) * (p.0 - mx)).sum();
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    if sxx <= 0.0 { None } else { Some(sxy / sxx) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slope_of_power_law() {
        let pts: Vec<(f64, f64)> = (1..10).map(|i| (i as f64, 3.0 * (i as f64).powf(-1.5))).collect();
        assert!((log_log_slope(&pts).unwrap() + 1.5).abs() < 1e-9);
        assert!(log_log_slope(&[(1.0, 1.0)]).is_none());
    }

    #[test]
    fn legend_goes_where_no_line_is() {
        let plot = |pts: Vec<(f64, f64)>| LinePlot {
            title: "t".into(),
            x_label: "x".into(),
            y_label: "y".into(),
            log_x: false,
            log_y: false,
            series: vec![Series { name: "gather=irradiance_cache".into(), points: pts }],
        };
        let at = |pts: Vec<(f64, f64)>| format!("{:?}", legend_corner(&plot(pts), &[], (0.0, 1.0), (0.0, 1.0)));
        // A line falling from the upper left to the lower right: the upper right is free.
        assert_eq!(at(vec![(0.0, 1.0), (1.0, 0.0)]), "UpperRight");
        // Points in the upper right corner (as the quick experiment's `direct` cells): elsewhere.
        assert_ne!(at(vec![(0.9, 0.95), (0.95, 0.9), (0.0, 0.0)]), "UpperRight");
        // A rising line leaves the upper left free.
        assert_eq!(at(vec![(0.0, 0.0), (1.0, 1.0)]), "UpperLeft");
    }

    #[test]
    fn writes_png_and_svg() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        let plot = LinePlot {
            title: "t".into(),
            x_label: "x (s)".into(),
            y_label: "y".into(),
            log_x: true,
            log_y: true,
            series: vec![Series { name: "a".into(), points: vec![(1.0, 1.0), (10.0, 0.1)] }],
        };
        let (p, s) = line_plot(&dir.join("lines"), &plot).unwrap();
        assert!(std::fs::metadata(&p).unwrap().len() > 1000);
        assert!(std::fs::read_to_string(&s).unwrap().contains("<svg"));
        let bars = StackedBars {
            title: "b".into(),
            y_label: "MSE".into(),
            categories: vec!["x".into(), "y".into()],
            layers: vec![("bias²".into(), vec![1.0, 2.0]), ("variance".into(), vec![0.5, 0.1])],
        };
        bar_plot(&dir.join("bars"), &bars).unwrap();
    }
}
