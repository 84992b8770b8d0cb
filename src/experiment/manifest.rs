//! Experiment manifests: parsing, validation and expansion into cells.
//!
//! A manifest names a scene, a resolution, a reference, a `[base]` configuration and
//! either a `[sweep]` (cartesian product of axes, with `exclude` rules and `repeats`)
//! or a list of named `[[configs]]`. Every key of `[base]`, of a sweep axis and of a
//! named configuration is a [`RenderConfig`] key: values are merged as TOML and
//! deserialised by the same code that rejects unknown keys everywhere else, so a new
//! integrator or strategy needs no change here. Every cell is validated
//! ([`registry::validate`]) before anything renders; errors name `file:line`.

pub use super::scene_spec::SceneSpec;
use super::scene_spec::parse_scenes;
use crate::config::RenderConfig;
use crate::registry;
use anyhow::{Result, anyhow, bail};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use toml::{Spanned, Value};

/// Seed of the reference render when `[reference]` does not set one: distinct from
/// the cells' default seed so the reference's noise is not correlated with theirs.
pub const REFERENCE_SEED: u64 = 0x5EF_E2E4_CE00;

/// Most cells a manifest may expand to (a typo such as `repeats = 99999999` is an
/// error, not hours of expansion).
pub const MAX_CELLS: usize = 100_000;

/// Keys that belong at the top level of a manifest, not in a configuration.
const TOP_LEVEL_ONLY: &[&str] = &["resolution"];

type SpannedTable = BTreeMap<String, Spanned<Value>>;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawManifest {
    name: Option<String>,
    description: Option<String>,
    /// Read with its spans by [`parse_scenes`].
    #[serde(rename = "scene")]
    _scene: serde::de::IgnoredAny,
    resolution: Spanned<[u32; 2]>,
    repeats: Option<Spanned<u32>>,
    reference: Spanned<SpannedTable>,
    base: Option<Spanned<SpannedTable>>,
    sweep: Option<Spanned<SpannedTable>>,
    configs: Option<Spanned<Vec<Spanned<SpannedTable>>>>,
    component: Option<Spanned<String>>,
    strategies: Option<Spanned<bool>>,
}

/// Where the reference image comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum ReferenceSpec {
    /// Rendered with this configuration (cached by content hash).
    Render(Box<RenderConfig>),
    /// Read from an EXR file.
    File(PathBuf),
}

/// One render of an experiment: a configuration and a repeat.
#[derive(Clone, Debug, PartialEq)]
pub struct Cell {
    /// Position in expansion order (shards take `index % N`).
    pub index: usize,
    /// Index of the configuration (cells of one configuration differ only in seed).
    pub config_index: usize,
    /// Index into [`Manifest::scenes`].
    pub scene: usize,
    /// File stem of this cell's outputs (unique within the experiment).
    pub stem: String,
    /// Human-readable configuration label (`gather=direct photons=20000` or a name).
    pub label: String,
    /// Strategy: the configuration's non-numeric axis values (lines in plots).
    pub group: String,
    /// The swept values of this configuration in axis order (`name` for named configurations).
    pub values: Vec<(String, Value)>,
    /// Repeat number (0-based); the seed is the configuration's seed + repeat.
    pub repeat: u32,
    /// The complete configuration rendered.
    pub config: RenderConfig,
    /// The part of the image measured (`direct`, `indirect`, `caustic`), if not all.
    pub component: Option<String>,
    /// Whether the cell also writes its per-strategy images (manifest `strategies`,
    /// for integrators that have them: an extra, untimed render).
    pub strategies: bool,
}

/// A parsed, validated and expanded manifest.
#[derive(Clone, Debug)]
pub struct Manifest {
    /// The manifest file.
    pub path: PathBuf,
    /// Directory relative paths are resolved against.
    pub dir: PathBuf,
    /// Experiment name (default: the file stem).
    pub name: String,
    /// Free text shown in the summary.
    pub description: String,
    /// The manifest text (copied next to the results).
    pub text: String,
    /// Scenes (several make `scene` the outermost axis).
    pub scenes: Vec<SceneSpec>,
    /// Image size.
    pub resolution: [u32; 2],
    /// Reference.
    pub reference: ReferenceSpec,
    /// Swept keys in manifest order (`name` for named configurations).
    pub axes: Vec<String>,
    /// Axes whose values are all numbers (candidates for convergence plots).
    pub numeric_axes: Vec<String>,
    /// Repeats (independent seeds) per configuration.
    pub repeats: u32,
    /// All cells in expansion order.
    pub cells: Vec<Cell>,
    /// `component`: the part of the image measured, rendered as the integrators'
    /// extra image of that name, for the cells and the reference alike.
    pub component: Option<String>,
    /// `strategies = true`: cells whose integrator has per-strategy images (`--aov
    /// strategies`) write them, and the report shows them.
    pub strategies: bool,
}

pub use crate::scene::loader::line_col;

struct Loc<'a> {
    file: &'a Path,
    text: &'a str,
}

impl Loc<'_> {
    fn at(&self, span: std::ops::Range<usize>) -> String {
        let (l, _) = line_col(self.text, span.start);
        format!("{}:{l}", self.file.display())
    }
}

/// Text of a value for labels and file names (strings without quotes).
pub fn value_text(v: &Value) -> String {
    match v {
        Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

/// Equality of TOML values where `1` and `1.0` are equal.
pub fn value_eq(a: &Value, b: &Value) -> bool {
    match (a, b) {
        (Value::Integer(x), Value::Float(y)) | (Value::Float(y), Value::Integer(x)) => *x as f64 == *y,
        _ => a == b,
    }
}

fn slug(s: &str) -> String {
    let out: String = s.chars().map(|c| if c.is_ascii_alphanumeric() || c == '.' || c == '-' { c } else { '_' }).collect();
    out.trim_matches('_').to_string()
}

/// Components a manifest can measure (extra images of `path` and `photon`).
pub const COMPONENTS: &[&str] = &["direct", "indirect", "caustic"];

/// Checks `component`: a known name that every configuration's integrator (and a
/// rendered reference's) can write.
fn check_component(c: &Spanned<String>, loc: &Loc, configs: &[(String, RenderConfig)], reference: &ReferenceSpec) -> Result<String> {
    let name = c.get_ref();
    let at = loc.at(c.span());
    if !COMPONENTS.contains(&name.as_str()) {
        bail!("{at}: component `{name}` is not one of {}", COMPONENTS.join(", "));
    }
    let refcfg = match reference {
        ReferenceSpec::Render(r) => Some(r.as_ref()),
        ReferenceSpec::File(_) => bail!("{at}: component `{name}` needs a rendered reference, not [reference] file"),
    };
    for cfg in configs.iter().map(|(_, c)| c).chain(refcfg) {
        let mut integ = registry::make_integrator_with(cfg, true).map_err(|e| anyhow!("{at}: {e:#}"))?;
        integ.set_output(name).map_err(|e| anyhow!("{at}: component `{name}`: {e:#}"))?;
    }
    Ok(name.clone())
}

/// The extra image of per-technique contributions (bidirectional integrators).
pub const STRATEGIES_AOV: &str = "strategies";

/// For `strategies = true`: which configurations' integrators write per-strategy
/// images (at least one must).
fn check_strategies(s: &Spanned<bool>, loc: &Loc, configs: &[(String, RenderConfig)]) -> Result<Vec<bool>> {
    if !*s.get_ref() {
        return Ok(vec![false; configs.len()]);
    }
    let mut has = Vec::with_capacity(configs.len());
    for (_, cfg) in configs {
        let mut integ = registry::make_integrator_with(cfg, true).map_err(|e| anyhow!("{}: {e:#}", loc.at(s.span())))?;
        has.push(integ.set_output(STRATEGIES_AOV).is_ok());
    }
    if !has.contains(&true) {
        bail!("{}: strategies = true, but no configuration's integrator writes per-strategy images (bdpt and vcm do)", loc.at(s.span()));
    }
    Ok(has)
}

/// Checks one key/value pair: a common key of [`RenderConfig`] or a parameter some
/// plug-in declares, with the declared type (whether the chosen plug-ins use it is
/// checked when the configuration is validated).
fn check_key(key: &str, value: &Value) -> anyhow::Result<()> {
    if TOP_LEVEL_ONLY.contains(&key) {
        return Err(anyhow::anyhow!("`{key}` is set once at the top level of the manifest, not per configuration"));
    }
    let cat = crate::registry::catalogue();
    let def = cat.find(key).ok_or_else(|| anyhow::anyhow!("unknown key `{key}` (`photonlab plugins` lists every parameter)"))?;
    (def.check)(value).map_err(|e| anyhow::anyhow!("`{key}`: {e}"))?;
    let mut t = toml::Table::new();
    t.insert(key.to_string(), value.clone());
    t.try_into::<RenderConfig>().map(|_| ()).map_err(|e| anyhow::anyhow!(e.message().replace('\n', " ")))
}

/// Builds a configuration from layers of key/values (later layers win).
fn build_config(layers: &[&[(String, Value)]]) -> anyhow::Result<RenderConfig> {
    let mut t = toml::Table::new();
    for layer in layers {
        for (k, v) in *layer {
            t.insert(k.clone(), v.clone());
        }
    }
    t.try_into::<RenderConfig>().map_err(|e| anyhow::anyhow!(e.message().replace('\n', " ")))
}

/// One configuration before repeats: its key/values, label and where it was written.
struct ConfigDraft {
    values: Vec<(String, Value)>,
    /// Span per value (for blaming a line).
    spans: Vec<std::ops::Range<usize>>,
    label: String,
    group: String,
    stem: String,
    /// The whole entry's span (named configuration) or the sweep's.
    span: std::ops::Range<usize>,
    /// For named configurations: key/values other than `name`.
    overrides: Vec<(String, Value)>,
    /// A named configuration (its `overrides` are its keys, even when there are none).
    named: bool,
}

impl Manifest {
    /// Reads, validates and expands a manifest file.
    pub fn load(path: &Path) -> Result<Manifest> {
        let text = std::fs::read_to_string(path).map_err(|e| anyhow!("{}: cannot read manifest: {e}", path.display()))?;
        let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Manifest::parse(&text, path, &dir)
    }

    /// Parses manifest text; `path` is used in messages, `dir` for relative paths.
    pub fn parse(text: &str, path: &Path, dir: &Path) -> Result<Manifest> {
        let file = path.display();
        let raw: RawManifest = toml::from_str(text).map_err(|e| {
            let msg = e.message().replace('\n', " ");
            match e.span() {
                Some(s) => anyhow!("{file}:{}: {msg}", line_col(text, s.start).0),
                None => anyhow!("{file}: {msg}"),
            }
        })?;
        let loc = Loc { file: path, text };
        let name = raw.name.clone().unwrap_or_else(|| path.file_stem().map_or("experiment".into(), |s| s.to_string_lossy().into_owned()));
        if slug(&name) != name || name.is_empty() {
            bail!("{file}: name `{name}` must be letters, digits, `.`, `-` or `_` (it names the results directory)");
        }
        let resolution = *raw.resolution.get_ref();
        if resolution[0] == 0 || resolution[1] == 0 {
            bail!("{}: resolution must be positive, got {}x{}", loc.at(raw.resolution.span()), resolution[0], resolution[1]);
        }
        let res_value = Value::Array(vec![Value::Integer(resolution[0] as i64), Value::Integer(resolution[1] as i64)]);
        let scenes = parse_scenes(text, path, dir)?;

        // Reference.
        let reference = {
            let r = raw.reference.get_ref();
            if let Some(f) = r.get("file") {
                if scenes.len() > 1 {
                    bail!(
                        "{}: [reference] file: one reference file cannot serve {} scenes; render the references instead",
                        loc.at(f.span()),
                        scenes.len()
                    );
                }
                if let Some((k, v)) = r.iter().find(|(k, _)| k.as_str() != "file") {
                    bail!("{}: [reference] `{k}`: a reference read from `file` takes no render settings", loc.at(v.span()));
                }
                let Value::String(s) = f.get_ref() else { bail!("{}: [reference] file must be a string path", loc.at(f.span())) };
                ReferenceSpec::File(dir.join(s))
            } else {
                let mut kv = Vec::new();
                for (k, v) in r {
                    check_key(k, v.get_ref()).map_err(|e| anyhow!("{}: [reference] {k}: {e}", loc.at(v.span())))?;
                    kv.push((k.clone(), v.get_ref().clone()));
                }
                if !r.contains_key("seed") {
                    kv.push(("seed".into(), Value::Integer(REFERENCE_SEED as i64)));
                }
                kv.push(("resolution".into(), res_value.clone()));
                let cfg = build_config(&[&kv]).map_err(|e| anyhow!("{}: [reference]: {e}", loc.at(raw.reference.span())))?;
                registry::validate(&cfg).map_err(|e| anyhow!("{}: [reference]: {e}", loc.at(raw.reference.span())))?;
                ReferenceSpec::Render(Box::new(cfg))
            }
        };

        // Base.
        let mut base: Vec<(String, Value)> = Vec::new();
        if let Some(b) = &raw.base {
            let mut entries: Vec<(&String, &Spanned<Value>)> = b.get_ref().iter().collect();
            entries.sort_by_key(|(_, v)| v.span().start);
            for (k, v) in entries {
                check_key(k, v.get_ref()).map_err(|e| anyhow!("{}: [base] {k}: {e}", loc.at(v.span())))?;
                base.push((k.clone(), v.get_ref().clone()));
            }
        }

        let mut repeats = raw.repeats.as_ref().map(|r| (*r.get_ref(), r.span()));
        let (drafts, axes, numeric_axes) = match (&raw.sweep, &raw.configs) {
            (Some(s), Some(c)) => bail!(
                "{}: a manifest has either a [sweep] or a list of [[configs]], not both (the [sweep] is at {})",
                loc.at(c.span()),
                loc.at(s.span())
            ),
            (Some(s), None) => expand_sweep(s, &loc, &mut repeats)?,
            (None, Some(c)) => named_configs(c, &loc)?,
            (None, None) => {
                let d = ConfigDraft {
                    values: vec![],
                    spans: vec![],
                    label: "base".into(),
                    group: "base".into(),
                    stem: "base".into(),
                    span: 0..0,
                    overrides: vec![],
                    named: false,
                };
                (vec![d], vec![], vec![])
            }
        };
        let (repeats, repeats_span) = repeats.unwrap_or((1, 0..0));
        if repeats == 0 {
            bail!("{}: repeats must be at least 1", loc.at(repeats_span));
        }
        if (repeats as usize).saturating_mul(drafts.len()).saturating_mul(scenes.len()) > MAX_CELLS {
            bail!(
                "{}: {} configuration(s) × {} scene(s) × {repeats} repeats is more than {MAX_CELLS} cells",
                loc.at(repeats_span),
                drafts.len(),
                scenes.len()
            );
        }

        // Build and validate every cell before anything renders.
        let mut configs = Vec::new();
        let mut never_used: Vec<String> = base.iter().map(|(k, _)| k.clone()).collect();
        let mut stems: BTreeMap<String, usize> = BTreeMap::new();
        let res_layer = vec![("resolution".to_string(), res_value.clone())];
        for (ci, d) in drafts.iter().enumerate() {
            let own: &[(String, Value)] = if d.named || !d.overrides.is_empty() { &d.overrides } else { &d.values };
            let cfg = build_config(&[&base, own, &res_layer])
                .map_err(|e| anyhow!("{}: configuration `{}`: {e}", loc.at(d.span.clone()), d.label))?;
            // A [base] key (not overridden here) only has to be used by some configuration.
            let from_base = |k: &str| base.iter().any(|(b, _)| b == k) && !own.iter().any(|(o, _)| o == k);
            let checked = registry::validate_allowing(&cfg, &from_base);
            let mut cfg = cfg;
            if let Ok(unused) = &checked {
                never_used.retain(|k| unused.contains(k));
                // The configuration keeps only the [base] keys its plug-ins read.
                for k in unused {
                    cfg.params.remove(k);
                }
            }
            if let Err(e) = checked {
                // Blame the first swept value that is invalid on its own over the base,
                // else the configuration (the combination is what fails).
                let mut blame = d.span.clone();
                for (i, kv) in own.iter().enumerate() {
                    let single = build_config(&[&base, std::slice::from_ref(kv), &res_layer]);
                    if single.map(|c| registry::validate(&c).is_err()).unwrap_or(true) {
                        blame = d.spans.get(i).cloned().unwrap_or(blame);
                        break;
                    }
                }
                bail!("{}: configuration `{}`: {e}", loc.at(blame), d.label);
            }
            let mut stem = d.stem.clone();
            let n = stems.entry(stem.clone()).or_insert(0);
            *n += 1;
            if *n > 1 {
                stem = format!("{stem}_{ci}");
            }
            configs.push((stem, cfg));
        }
        if let (Some(k), Some((_, cfg))) = (never_used.first(), configs.first()) {
            let at = raw.base.as_ref().and_then(|b| b.get_ref().get(k)).map_or(0..0, |v| v.span());
            let chosen = format!("integrator `{}` …", cfg.integrator);
            bail!("{}: [base] {k}: no configuration uses it: {}", loc.at(at), registry::unused_error(k, &chosen));
        }
        // Several scenes: the scene is the outermost axis of every configuration.
        let multi = scenes.len() > 1;
        let component = match &raw.component {
            Some(c) => Some(check_component(c, &loc, &configs, &reference)?),
            None => None,
        };
        let strategies = match &raw.strategies {
            Some(s) => check_strategies(s, &loc, &configs)?,
            None => vec![false; configs.len()],
        };
        let mut cells = Vec::new();
        for (si, sc) in scenes.iter().enumerate() {
            for (di, (d, (stem, cfg))) in drafts.iter().zip(&configs).enumerate() {
                let (mut label, mut group, mut stem, mut values) = (d.label.clone(), d.group.clone(), stem.clone(), d.values.clone());
                if multi {
                    let tag = format!("scene={}", sc.name());
                    label = if d.values.is_empty() { tag.clone() } else { format!("{tag} {label}") };
                    group = if d.values.is_empty() || group == "all" { tag.clone() } else { format!("{tag} {group}") };
                    stem = format!("scene-{}_{stem}", slug(&sc.name()));
                    values.insert(0, ("scene".into(), Value::String(sc.name())));
                }
                for r in 0..repeats {
                    let mut c = cfg.clone();
                    c.seed = cfg.seed.wrapping_add(r as u64);
                    cells.push(Cell {
                        index: cells.len(),
                        config_index: si * drafts.len() + di,
                        scene: si,
                        stem: format!("{stem}_r{r}"),
                        label: label.clone(),
                        group: group.clone(),
                        values: values.clone(),
                        repeat: r,
                        config: c,
                        component: component.clone(),
                        strategies: strategies[di],
                    });
                }
            }
        }
        let mut axes = axes;
        if multi {
            axes.insert(0, "scene".into());
        }
        if cells.is_empty() {
            bail!("{file}: every configuration is excluded: nothing to run");
        }
        Ok(Manifest {
            path: path.to_path_buf(),
            dir: dir.to_path_buf(),
            name,
            description: raw.description.unwrap_or_default(),
            text: text.to_string(),
            scenes,
            resolution,
            reference,
            axes,
            numeric_axes,
            repeats,
            cells,
            component,
            strategies: strategies.contains(&true),
        })
    }

    /// Number of configurations (cells / repeats).
    pub fn configurations(&self) -> usize {
        self.cells.last().map_or(0, |c| c.config_index + 1)
    }
}

type Expanded = (Vec<ConfigDraft>, Vec<String>, Vec<String>);

fn expand_sweep(s: &Spanned<SpannedTable>, loc: &Loc, repeats: &mut Option<(u32, std::ops::Range<usize>)>) -> Result<Expanded> {
    let mut axes: Vec<(String, Vec<Value>, std::ops::Range<usize>)> = Vec::new();
    let mut exclude: Option<&Spanned<Value>> = None;
    let mut entries: Vec<(&String, &Spanned<Value>)> = s.get_ref().iter().collect();
    // Axes expand in the order they are written (the first varies slowest).
    entries.sort_by_key(|(_, v)| v.span().start);
    for (k, v) in entries {
        let at = loc.at(v.span());
        match k.as_str() {
            "exclude" => exclude = Some(v),
            "repeats" => {
                if let Some((_, span)) = repeats {
                    bail!("{at}: repeats is set twice (also at {})", loc.at(span.clone()));
                }
                let n = v.get_ref().as_integer().filter(|n| (1..=u32::MAX as i64).contains(n));
                let Some(n) = n else { bail!("{at}: [sweep] repeats must be a whole number >= 1") };
                *repeats = Some((n as u32, v.span()));
            }
            _ => {
                let Value::Array(vals) = v.get_ref() else {
                    bail!("{at}: [sweep] {k}: an axis is a list of values, e.g. {k} = [{}] (a single setting goes in [base])", v.get_ref())
                };
                if vals.is_empty() {
                    bail!("{at}: [sweep] {k}: empty axis (give at least one value)");
                }
                for x in vals {
                    check_key(k, x).map_err(|e| anyhow!("{at}: [sweep] {k} = {x}: {e}"))?;
                }
                for (i, x) in vals.iter().enumerate() {
                    if vals[..i].iter().any(|y| value_eq(x, y)) {
                        bail!("{at}: [sweep] {k}: value {x} appears twice");
                    }
                }
                axes.push((k.clone(), vals.clone(), v.span()));
            }
        }
    }
    if axes.is_empty() {
        bail!("{}: [sweep] has no axes", loc.at(s.span()));
    }
    // Exclude rules: tables of axis = value; a configuration matching every entry of
    // one rule is skipped.
    let mut rules: Vec<Vec<(usize, Value)>> = Vec::new();
    if let Some(ex) = exclude {
        let at = loc.at(ex.span());
        let Value::Array(list) = ex.get_ref() else {
            bail!("{at}: [sweep] exclude must be a list of tables, e.g. [{{ gather = \"direct\", photons = 1000 }}]")
        };
        for (ri, r) in list.iter().enumerate() {
            let Value::Table(t) = r else { bail!("{at}: exclude rule {}: must be a table like {{ key = value }}", ri + 1) };
            if t.is_empty() {
                bail!("{at}: exclude rule {} is empty (it would exclude everything)", ri + 1);
            }
            let mut rule = Vec::new();
            for (k, v) in t {
                let Some(ai) = axes.iter().position(|a| &a.0 == k) else {
                    bail!(
                        "{at}: exclude rule {}: `{k}` is not a sweep axis (axes: {})",
                        ri + 1,
                        axes.iter().map(|a| a.0.as_str()).collect::<Vec<_>>().join(", ")
                    )
                };
                if !axes[ai].1.iter().any(|x| value_eq(x, v)) {
                    bail!("{at}: exclude rule {}: {k} = {v} is not a value of the axis", ri + 1);
                }
                rule.push((ai, v.clone()));
            }
            rules.push(rule);
        }
    }
    let numeric: Vec<bool> = axes.iter().map(|a| a.1.iter().all(|v| matches!(v, Value::Integer(_) | Value::Float(_)))).collect();
    let total = axes.iter().try_fold(1usize, |t, a| t.checked_mul(a.1.len()).filter(|&t| t <= MAX_CELLS));
    let Some(total) = total else { bail!("{}: [sweep] expands to more than {MAX_CELLS} configurations", loc.at(s.span())) };
    let mut drafts = Vec::new();
    for flat in 0..total {
        // Mixed-radix digits, the last axis varying fastest.
        let mut idx = vec![0usize; axes.len()];
        let mut rem = flat;
        for (i, a) in axes.iter().enumerate().rev() {
            idx[i] = rem % a.1.len();
            rem /= a.1.len();
        }
        if rules.iter().any(|rule| rule.iter().all(|(ai, v)| value_eq(&axes[*ai].1[idx[*ai]], v))) {
            continue;
        }
        let values: Vec<(String, Value)> = axes.iter().zip(&idx).map(|(a, &i)| (a.0.clone(), a.1[i].clone())).collect();
        let label = values.iter().map(|(k, v)| format!("{k}={}", value_text(v))).collect::<Vec<_>>().join(" ");
        let group = {
            let g: Vec<String> =
                values.iter().zip(&numeric).filter(|(_, n)| !**n).map(|((k, v), _)| format!("{k}={}", value_text(v))).collect();
            if g.is_empty() { "all".to_string() } else { g.join(" ") }
        };
        let stem = values.iter().map(|(k, v)| format!("{}-{}", slug(k), slug(&value_text(v)))).collect::<Vec<_>>().join("_");
        drafts.push(ConfigDraft {
            spans: axes.iter().map(|a| a.2.clone()).collect(),
            values,
            label,
            group,
            stem,
            span: s.span(),
            overrides: vec![],
            named: false,
        });
    }
    let names = axes.iter().map(|a| a.0.clone()).collect();
    let numeric_axes = axes.iter().zip(&numeric).filter(|(a, n)| **n && a.1.len() >= 2).map(|(a, _)| a.0.clone()).collect();
    Ok((drafts, names, numeric_axes))
}

fn named_configs(c: &Spanned<Vec<Spanned<SpannedTable>>>, loc: &Loc) -> Result<Expanded> {
    if c.get_ref().is_empty() {
        bail!("{}: [[configs]] is empty", loc.at(c.span()));
    }
    let mut drafts: Vec<ConfigDraft> = Vec::new();
    for (i, entry) in c.get_ref().iter().enumerate() {
        let at = loc.at(entry.span());
        let t = entry.get_ref();
        let name = match t.get("name").map(|v| v.get_ref()) {
            Some(Value::String(s)) if !s.trim().is_empty() => s.clone(),
            _ => bail!("{at}: [[configs]] entry {} needs a `name = \"...\"`", i + 1),
        };
        if drafts.iter().any(|d| d.label == name) {
            bail!("{at}: configuration name `{name}` is used twice");
        }
        // Optional `group`: configurations sharing it are one line in the plots.
        let group = match t.get("group").map(|v| v.get_ref()) {
            None => name.clone(),
            Some(Value::String(g)) if !g.trim().is_empty() => g.clone(),
            Some(_) => bail!("{at}: [[configs]] `{name}`: group must be a non-empty string"),
        };
        let mut entries: Vec<(&String, &Spanned<Value>)> = t.iter().filter(|(k, _)| !matches!(k.as_str(), "name" | "group")).collect();
        entries.sort_by_key(|(_, v)| v.span().start);
        let mut overrides = Vec::new();
        let mut spans = Vec::new();
        for (k, v) in entries {
            check_key(k, v.get_ref()).map_err(|e| anyhow!("{}: [[configs]] `{name}` {k}: {e}", loc.at(v.span())))?;
            overrides.push((k.clone(), v.get_ref().clone()));
            spans.push(v.span());
        }
        drafts.push(ConfigDraft {
            values: vec![("name".into(), Value::String(name.clone()))],
            spans,
            group,
            stem: slug(&name),
            label: name,
            span: entry.span(),
            overrides,
            named: true,
        });
    }
    Ok((drafts, vec!["name".into()], vec![]))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Manifest> {
        Manifest::parse(text, Path::new("m.toml"), Path::new("."))
    }

    const HEAD: &str = "scene = \"cornell\"\nresolution = [8, 8]\n[reference]\nspp = 4\n";

    #[test]
    fn sweep_expands_in_order_with_exclusions_and_repeats() {
        let m = parse(&format!(
            "{HEAD}[base]\nspp = 2\n[sweep]\nsampler = [\"random\", \"halton\"]\nmax_depth = [1, 2, 3]\nrepeats = 2\nexclude = [{{ sampler = \"random\", max_depth = 2 }}]\n"
        ))
        .unwrap();
        assert_eq!(m.axes, ["sampler", "max_depth"]);
        assert_eq!(m.numeric_axes, ["max_depth"]);
        assert_eq!(m.repeats, 2);
        assert_eq!(m.cells.len(), 10);
        let labels: Vec<&str> = m.cells.iter().step_by(2).map(|c| c.label.as_str()).collect();
        assert_eq!(
            labels,
            [
                "sampler=random max_depth=1",
                "sampler=random max_depth=3",
                "sampler=halton max_depth=1",
                "sampler=halton max_depth=2",
                "sampler=halton max_depth=3"
            ]
        );
        assert_eq!(m.cells[0].group, "sampler=random");
        assert_eq!((m.cells[0].config.seed, m.cells[1].config.seed), (0, 1));
        assert_eq!(m.cells[1].stem, "sampler-random_max_depth-1_r1");
        assert_eq!(m.cells[3].config.max_depth, Some(3));
        assert_eq!(m.cells[3].config.spp, 2);
        assert_eq!(m.cells[3].config.resolution, Some([8, 8]));
        match &m.reference {
            ReferenceSpec::Render(c) => assert_eq!((c.spp, c.seed), (4, REFERENCE_SEED)),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn several_scenes_are_the_outer_axis() {
        let m = parse("scene = [\"cornell\", \"furnace\"]\nresolution = [8, 8]\n[reference]\nspp = 4\n[sweep]\nspp = [1, 2]\n").unwrap();
        assert_eq!(m.axes, ["scene", "spp"]);
        assert_eq!(m.cells.len(), 4);
        assert_eq!(m.cells[2].label, "scene=furnace spp=1");
        assert_eq!(m.cells[2].group, "scene=furnace");
        assert_eq!(m.cells[2].stem, "scene-furnace_spp-1_r0");
        assert_eq!((m.cells[2].scene, m.cells[2].config_index), (1, 2));
        assert!(
            format!("{:#}", parse("scene = [\"cornell\", \"cornell\"]\nresolution = [8, 8]\n[reference]\nspp = 4\n").unwrap_err())
                .contains("twice")
        );
    }

    #[test]
    fn named_configurations() {
        let m =
            parse(&format!("repeats = 3\n{HEAD}[[configs]]\nname = \"a\"\nspp = 1\n[[configs]]\nname = \"b b\"\nsampler = \"random\"\n"))
                .unwrap();
        assert_eq!(m.cells.len(), 6);
        assert_eq!(m.cells[3].label, "b b");
        assert_eq!(m.cells[3].stem, "b_b_r0");
        assert_eq!(m.cells[0].config.spp, 1);
        assert_eq!(m.cells[3].config.sampler, "random");
        // A configuration of the base alone: only a name.
        let m = parse(&format!("{HEAD}[base]\nspp = 3\n[[configs]]\nname = \"base\"\n[[configs]]\nname = \"c\"\nspp = 1\n")).unwrap();
        assert_eq!((m.cells[0].label.as_str(), m.cells[0].config.spp, m.cells[1].config.spp), ("base", 3, 1));
    }

    fn err(text: &str) -> String {
        format!("{:#}", parse(text).unwrap_err())
    }

    #[test]
    fn errors_name_the_line() {
        let e = err(&format!("{HEAD}[sweep]\nspp = [1, 2]\nbogus = [1]\n"));
        assert!(e.starts_with("m.toml:7:") && e.contains("bogus"), "{e}");
        let e = err(&format!("{HEAD}[sweep]\nspp = []\n"));
        assert!(e.starts_with("m.toml:6:") && e.contains("empty axis"), "{e}");
        let e = err(&format!("{HEAD}[sweep]\nsampler = [\"latin\"]\n"));
        assert!(e.starts_with("m.toml:6:") && e.contains("latin") && e.contains("known"), "{e}");
        let e = err(&format!("{HEAD}[base]\nspp = 4\n[sweep]\nrr = [\"fixed\", \"off\"]\n"));
        assert!(e.starts_with("m.toml:8:") && e.contains("max_depth"), "{e}");
        let e = err(&format!("{HEAD}[sweep]\nspp = [0, 1]\n"));
        assert!(e.starts_with("m.toml:6:") && e.contains("spp"), "{e}");
        let e = err(&format!("{HEAD}[sweep]\nspp = [-1]\n"));
        assert!(e.starts_with("m.toml:6:"), "{e}");
        let e = err(&format!("{HEAD}[sweep]\nspp = [1]\nexclude = [{{ sampler = \"random\" }}]\n"));
        assert!(e.contains("not a sweep axis"), "{e}");
        let e = err(&format!("{HEAD}[sweep]\nspp = [1]\nexclude = [{{ spp = 1 }}]\n"));
        assert!(e.contains("nothing to run"), "{e}");
        let e = err("scene = \"cornel\"\nresolution = [8, 8]\n[reference]\nspp = 4\n");
        assert!(e.starts_with("m.toml:1:") && e.contains("known: cornell"), "{e}");
        let e = err(&format!("{HEAD}[base]\nresolution = [4, 4]\n"));
        assert!(e.starts_with("m.toml:6:") && e.contains("top level"), "{e}");
        let e = err(&format!("{HEAD}colour = 1\n"));
        assert!(e.starts_with("m.toml:") && e.contains("colour"), "{e}");
        let e = err(&format!("{HEAD}[sweep]\nspp = 4\n"));
        assert!(e.contains("list of values"), "{e}");
    }
}
