//! `index.html`: the experiment report a researcher opens in a browser. It holds the
//! summary (the text of `summary.md`, rendered with `pulldown-cmark`), every plot, and
//! an image comparison viewer (`assets/report.js`, inlined: no network needed).
//!
//! Beside it, `view/STEM.js` carries each cell's and reference's linear image as
//! RGBE (Ward's shared-exponent format, base64) inside a script: browsers refuse to
//! let a page opened from `file://` read image pixels or fetch files, but they load
//! scripts, so exposure and pixel read-out work on the radiance itself.

use super::cell::CellPaths;
use super::output::Row;
use super::summary::SummaryInfo;
use crate::film::{Film, write_atomic};
use anyhow::{Context, Result};
use serde_json::json;
use std::path::Path;

/// The viewer's script.
const REPORT_JS: &str = include_str!("../../assets/report.js");
/// The page's style sheet.
const REPORT_CSS: &str = include_str!("../../assets/report.css");

/// RGBE bytes (r, g, b mantissas and a shared exponent biased by 128) of an image.
pub fn rgbe(film: &Film) -> Vec<u8> {
    let mut out = Vec::with_capacity(film.pixels.len() * 4);
    for p in &film.pixels {
        let c = [p.x, p.y, p.z].map(|v| if v.is_finite() { v.max(0.0) } else { 0.0 });
        let v = c[0].max(c[1]).max(c[2]);
        if v < 1e-32 {
            out.extend_from_slice(&[0, 0, 0, 0]);
            continue;
        }
        // v = m · 2^e with m in [0.5, 1).
        let e = v.log2().floor() as i32 + 1;
        let scale = 256.0 / 2f32.powi(e);
        let m = c.map(|x| ((x * scale) as i32).clamp(0, 255) as u8);
        out.extend_from_slice(&[m[0], m[1], m[2], (e + 128).clamp(0, 255) as u8]);
    }
    out
}

/// Standard base64 (RFC 4648, with padding).
pub fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for ch in bytes.chunks(3) {
        let n = (ch[0] as u32) << 16 | (*ch.get(1).unwrap_or(&0) as u32) << 8 | *ch.get(2).unwrap_or(&0) as u32;
        for i in 0..4 {
            if i <= ch.len() {
                s.push(A[(n >> (18 - 6 * i) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// Writes `view/NAME.js` registering `film` with the viewer under `id`.
fn write_view_js(dir: &Path, id: &str, film: &Film) -> Result<String> {
    let rel = format!("view/{id}.js");
    let text = format!("PL.hdr({},{},{},\"{}\");\n", serde_json::to_string(id)?, film.width, film.height, base64(&rgbe(film)));
    write_atomic(&dir.join(&rel), text.as_bytes())?;
    Ok(rel)
}

/// The viewer script of a component image: `{"id", "js"}`.
fn view_component(dir: &Path, exr: &Path, id: &str) -> Result<serde_json::Value> {
    let film = Film::read_exr(exr).context("the report needs the component images")?;
    Ok(json!({"id": id, "js": write_view_js(dir, id, &film)?}))
}

/// Text safe inside `<script>`: JSON with `<` escaped.
fn script_json(v: &serde_json::Value) -> Result<String> {
    Ok(serde_json::to_string(v)?.replace('<', "\\u003c"))
}

/// Writes `dir/index.html` and `dir/view/*.js` from the finished rows and the
/// summary text.
pub fn write_report(dir: &Path, info: &SummaryInfo, rows: &[Row], summary_md: &str) -> Result<()> {
    let m = info.manifest;
    let mut refs = Vec::new();
    for r in info.references {
        let film = Film::read_exr(&dir.join(&r.file)).context("the report needs the reference images")?;
        let id = Path::new(&r.file).file_stem().map_or_else(|| format!("reference-{}", r.scene), |s| s.to_string_lossy().into_owned());
        let js = write_view_js(dir, &id, &film)?;
        let png = Path::new(&r.file).with_extension("png").to_string_lossy().into_owned();
        // The measured component's reference, viewable like the image.
        let comp = match (&r.component_file, &m.component) {
            (Some(f), Some(c)) => Some(view_component(dir, &dir.join(f), &format!("{id}.{c}"))?),
            _ => None,
        };
        refs.push(json!({"scene": r.scene, "id": id, "js": js, "png": png, "noise_relmse": r.noise_relmse,
            "component_noise_relmse": r.component_noise_relmse, "description": r.description, "comp": comp}));
    }
    let mut cells = Vec::new();
    for row in rows {
        let c = &row.rec;
        let p = CellPaths::new(dir, &c.cell);
        let film = Film::read_exr(&p.exr).with_context(|| format!("cell `{}`", c.cell))?;
        let js = write_view_js(dir, &c.cell, &film)?;
        let scene = m.cells.iter().find(|x| x.stem == c.cell).map_or(0, |x| x.scene);
        let rel = |name: &str| format!("cells/{}.{name}", c.cell);
        let comp = match &m.component {
            Some(k) => Some(view_component(dir, &p.exr.with_extension(format!("{k}.exr")), &format!("{}.{k}", c.cell))?),
            None => None,
        };
        // Per-strategy images (PNG), when the cell wrote them.
        let strategies: Vec<serde_json::Value> = c
            .strategies
            .iter()
            .flatten()
            .map(|n| {
                let png = p.strategy(n).1.file_name().map(|f| format!("cells/{}", f.to_string_lossy())).unwrap_or_default();
                json!({"name": n, "png": png})
            })
            .collect();
        cells.push(json!({
            "id": c.cell, "label": c.label, "repeat": c.repeat, "scene": scene, "js": js,
            "png": rel("png"), "relerr": rel("relerr.png"), "signed": rel("signed.png"),
            "worst_block": c.robust.worst_block, "worst_block_at": c.robust.worst_block_at,
            "relmse": c.metrics.relmse, "relmse_trimmed": c.robust.relmse_trimmed,
            // In display order (a JSON object's keys would come out sorted).
            "metrics": [
                ["relMSE", c.metrics.relmse], ["relMSE trimmed", c.robust.relmse_trimmed], ["SMAPE", c.robust.smape],
                ["RMSE", c.metrics.rmse], ["MAE", c.metrics.mae], ["worst block", c.robust.worst_block],
                ["worst block at", c.robust.worst_block_at], ["worst pixel share", c.robust.max_pixel_share],
                ["time (s)", c.time_total_s], ["seed", c.seed],
            ],
            "component": c.component, "comp": comp, "strategies": strategies,
        }));
    }
    let data = json!({
        "component_name": m.component, "name": m.name, "block": super::metrics::BLOCK, "signed_range": super::metrics::SIGNED_RANGE,
        "relerr_range": super::cell::RELERR_RANGE, "references": refs, "cells": cells,
    });
    let mut body = String::new();
    let opts = pulldown_cmark::Options::ENABLE_TABLES;
    pulldown_cmark::html::push_html(&mut body, pulldown_cmark::Parser::new_ext(summary_md, opts));
    let page = format!(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n<title>{title} — photonlab</title>\n\
         <style>{REPORT_CSS}</style></head>\n<body>\n<nav><b>{title}</b> <a href=\"#viewer\">viewer</a> \
         <a href=\"#summary\">summary</a> <a href=\"summary.md\">summary.md</a> <a href=\"cells.csv\">cells.csv</a></nav>\n\
         <section id=\"viewer\"><h2>Images</h2><div id=\"pl-viewer\">The image viewer needs JavaScript.</div></section>\n\
         <section id=\"summary\">{body}</section>\n<pre id=\"selftest-result\" hidden></pre>\n\
         <script>const PL_DATA = {data};</script>\n<script>{REPORT_JS}</script>\n</body></html>\n",
        title = html_escape(&m.name),
        data = script_json(&data)?,
    );
    write_atomic(&dir.join("index.html"), page.as_bytes())
}

fn html_escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Color;

    #[test]
    fn base64_known_values() {
        assert_eq!(base64(b""), "");
        assert_eq!(base64(b"f"), "Zg==");
        assert_eq!(base64(b"fo"), "Zm8=");
        assert_eq!(base64(b"foo"), "Zm9v");
        assert_eq!(base64(b"foobar"), "Zm9vYmFy");
        assert_eq!(base64(&[255, 254, 253]), "//79");
    }

    #[test]
    fn rgbe_round_trips_within_its_precision() {
        let mut f = Film::new(4, 1);
        f.pixels = vec![Color::new(1.0, 0.5, 0.25), Color::new(1000.0, 3.0, 0.0), Color::ZERO, Color::new(1e-5, 2e-5, 0.0)];
        let b = rgbe(&f);
        for (i, p) in f.pixels.iter().enumerate() {
            let e = b[4 * i + 3] as i32;
            for c in 0..3 {
                // The viewer's decoding: (m + 0.5) · 2^(e − 136), 0 when e = 0.
                let v = if e == 0 { 0.0 } else { (b[4 * i + c] as f32 + 0.5) * 2f32.powi(e - 136) };
                let want = p[c];
                let max = p.max_element();
                assert!((v - want).abs() <= max / 128.0 + 1e-30, "pixel {i} channel {c}: {v} vs {want}");
            }
        }
    }
}
