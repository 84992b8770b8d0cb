//! Mitsuba 3 XML → a tree of plug-in descriptions ([`Plugin`]) with every parameter
//! typed and located (`file:line`).
//!
//! This step knows the document syntax only: `<scene version>`, `<default>` and
//! `$name` substitution in attribute values, `<include>`, `id`/`<ref>`, the property
//! elements (`float`, `integer`, `boolean`, `string`, `rgb`, `spectrum` with one
//! value, `point`, `vector`, `transform`) and nested plug-ins. Which plug-ins and
//! parameters photonlab supports is decided by the readers in the sibling modules,
//! which take parameters out of a [`Plugin`] and then call [`Plugin::finish`]: a
//! parameter nobody took is an error naming file, line, element and name.

use super::transform;
use anyhow::{Result, anyhow, bail};
use glam::{Mat4, Vec3};
use std::cell::Cell;
use std::collections::HashMap;
use std::fmt;
use std::path::{Path, PathBuf};
use std::rc::Rc;

/// Deepest `<include>` nesting (a file including itself is caught by this).
const MAX_INCLUDE_DEPTH: usize = 16;

/// Where an element is: file and 1-based line.
#[derive(Clone, Debug)]
pub struct Loc {
    /// The XML file.
    pub file: Rc<PathBuf>,
    /// Line of the element's start tag.
    pub line: u32,
}

impl fmt::Display for Loc {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}", self.file.display(), self.line)
    }
}

impl Loc {
    /// Directory relative file names start from.
    pub fn dir(&self) -> &Path {
        self.file.parent().unwrap_or(Path::new(""))
    }
    /// Resolves a file name given in this file.
    pub fn resolve(&self, name: &str) -> PathBuf {
        self.dir().join(name)
    }
}

/// A parameter value.
#[derive(Clone, Debug)]
pub enum Value {
    /// `<float>`.
    Float(f64),
    /// `<integer>`.
    Int(i64),
    /// `<boolean>`.
    Bool(bool),
    /// `<string>`.
    Str(String),
    /// `<rgb>` or a one-value `<spectrum>`.
    Rgb(Vec3),
    /// `<point>`.
    Point(Vec3),
    /// `<vector>`.
    Vector(Vec3),
    /// `<transform>`.
    Transform(Mat4),
    /// A nested plug-in or a `<ref>`.
    Plugin(Rc<Plugin>),
}

impl Value {
    fn kind(&self) -> &'static str {
        match self {
            Value::Float(_) => "float",
            Value::Int(_) => "integer",
            Value::Bool(_) => "boolean",
            Value::Str(_) => "string",
            Value::Rgb(_) => "rgb",
            Value::Point(_) => "point",
            Value::Vector(_) => "vector",
            Value::Transform(_) => "transform",
            Value::Plugin(_) => "plug-in",
        }
    }
}

/// One parameter of a plug-in.
#[derive(Debug)]
pub struct Prop {
    /// Its `name` (empty for a nested plug-in without one).
    pub name: String,
    /// Its value.
    pub value: Value,
    /// Where it is.
    pub loc: Loc,
    used: Cell<bool>,
}

/// One plug-in element (`<bsdf type="diffuse">`, `<shape>`, …) with its parameters.
#[derive(Debug)]
pub struct Plugin {
    /// Element name: `bsdf`, `shape`, `emitter`, `texture`, `sensor`, `film`, …
    pub tag: String,
    /// Its `type` attribute.
    pub ty: String,
    /// Its `id`, if any.
    pub id: Option<String>,
    /// Where it is.
    pub loc: Loc,
    /// Parameters and nested plug-ins, in document order.
    pub props: Vec<Prop>,
}

impl Plugin {
    /// `<tag type="ty">` at `loc`, for messages.
    pub fn what(&self) -> String {
        format!("<{} type=\"{}\">", self.tag, self.ty)
    }

    /// An error located at this plug-in.
    pub fn err(&self, msg: impl fmt::Display) -> anyhow::Error {
        anyhow!("{}: {}: {msg}", self.loc, self.what())
    }

    fn take(&self, name: &str) -> Option<&Prop> {
        let p = self.props.iter().find(|p| p.name == name)?;
        p.used.set(true);
        Some(p)
    }

    fn wrong(&self, p: &Prop, want: &str) -> anyhow::Error {
        anyhow!("{}: {}: parameter `{}` must be {want}, got <{}>", p.loc, self.what(), p.name, p.value.kind())
    }

    /// A float (an integer is accepted too).
    pub fn float(&self, name: &str) -> Result<Option<f32>> {
        let Some(p) = self.take(name) else { return Ok(None) };
        let v = match &p.value {
            Value::Float(v) => *v as f32,
            Value::Int(v) => *v as f32,
            _ => return Err(self.wrong(p, "a <float>")),
        };
        if !v.is_finite() {
            bail!("{}: {}: parameter `{name}` must be finite, got {v}", p.loc, self.what());
        }
        Ok(Some(v))
    }

    /// A number or a name (IORs): `Ok(Some(Ok(number)))` or `Ok(Some(Err((name, loc))))`.
    #[allow(clippy::type_complexity)]
    pub fn number_or_name(&self, name: &str) -> Result<Option<std::result::Result<f32, (String, Loc)>>> {
        let Some(p) = self.props.iter().find(|p| p.name == name) else { return Ok(None) };
        if let Value::Str(s) = &p.value {
            p.used.set(true);
            return Ok(Some(Err((s.clone(), p.loc.clone()))));
        }
        Ok(self.float(name)?.map(Ok))
    }

    /// A float with a default.
    pub fn float_or(&self, name: &str, default: f32) -> Result<f32> {
        Ok(self.float(name)?.unwrap_or(default))
    }

    /// An integer.
    pub fn int(&self, name: &str) -> Result<Option<i64>> {
        let Some(p) = self.take(name) else { return Ok(None) };
        match &p.value {
            Value::Int(v) => Ok(Some(*v)),
            _ => Err(self.wrong(p, "an <integer>")),
        }
    }

    /// A boolean with a default.
    pub fn bool_or(&self, name: &str, default: bool) -> Result<bool> {
        let Some(p) = self.take(name) else { return Ok(default) };
        match &p.value {
            Value::Bool(v) => Ok(*v),
            _ => Err(self.wrong(p, "a <boolean>")),
        }
    }

    /// A string.
    pub fn string(&self, name: &str) -> Result<Option<(String, Loc)>> {
        let Some(p) = self.take(name) else { return Ok(None) };
        match &p.value {
            Value::Str(v) => Ok(Some((v.clone(), p.loc.clone()))),
            _ => Err(self.wrong(p, "a <string>")),
        }
    }

    /// A point, or a position given as a vector.
    pub fn point(&self, name: &str) -> Result<Option<Vec3>> {
        let Some(p) = self.take(name) else { return Ok(None) };
        match &p.value {
            Value::Point(v) | Value::Vector(v) => Ok(Some(*v)),
            _ => Err(self.wrong(p, "a <point>")),
        }
    }

    /// A vector (a point is accepted too).
    pub fn vector(&self, name: &str) -> Result<Option<Vec3>> {
        self.point(name)
    }

    /// A transform (identity when absent).
    pub fn transform(&self, name: &str) -> Result<Option<Mat4>> {
        let Some(p) = self.take(name) else { return Ok(None) };
        match &p.value {
            Value::Transform(m) => Ok(Some(*m)),
            _ => Err(self.wrong(p, "a <transform>")),
        }
    }

    /// A spectrum-like parameter: a number (grey), an `<rgb>`, a one-value
    /// `<spectrum>` or a nested / referenced texture plug-in.
    pub fn spectrum(&self, name: &str) -> Result<Option<SpectrumValue>> {
        let Some(p) = self.take(name) else { return Ok(None) };
        match &p.value {
            Value::Float(v) => Ok(Some(SpectrumValue::Rgb(Vec3::splat(*v as f32)))),
            Value::Int(v) => Ok(Some(SpectrumValue::Rgb(Vec3::splat(*v as f32)))),
            Value::Rgb(c) => Ok(Some(SpectrumValue::Rgb(*c))),
            Value::Plugin(t) if t.tag == "texture" => Ok(Some(SpectrumValue::Texture(t.clone()))),
            _ => Err(self.wrong(p, "a <float>, <rgb>, <spectrum> or <texture>")),
        }
    }

    /// The nested (or referenced) plug-ins with element name `tag`, named or not.
    pub fn children(&self, tag: &str) -> Vec<Rc<Plugin>> {
        let mut out = Vec::new();
        for p in &self.props {
            if let Value::Plugin(c) = &p.value
                && c.tag == tag
                && p.name.is_empty()
            {
                p.used.set(true);
                out.push(c.clone());
            }
        }
        out
    }

    /// At most one nested plug-in with element name `tag`.
    pub fn child(&self, tag: &str) -> Result<Option<Rc<Plugin>>> {
        let mut c = self.children(tag);
        if c.len() > 1 {
            return Err(c[1].err(format!("{} allows only one nested <{tag}>", self.what())));
        }
        Ok(c.pop())
    }

    /// Marks a parameter as read without reading it (for parameters that have no
    /// effect in photonlab and are documented as such).
    pub fn ignore(&self, name: &str) {
        let _ = self.take(name);
    }

    /// Fails on the first parameter or nested plug-in nobody took.
    pub fn finish(&self) -> Result<()> {
        if let Some(p) = self.props.iter().find(|p| !p.used.get()) {
            if let Value::Plugin(c) = &p.value
                && p.name.is_empty()
            {
                bail!("{}: {}: nested {} is not supported here", c.loc, self.what(), c.what());
            }
            bail!("{}: {}: parameter `{}` (<{}>) is not supported by photonlab", p.loc, self.what(), p.name, p.value.kind());
        }
        Ok(())
    }
}

/// A colour parameter: constant or textured.
#[derive(Clone, Debug)]
pub enum SpectrumValue {
    /// Constant linear RGB.
    Rgb(Vec3),
    /// A `<texture>` plug-in.
    Texture(Rc<Plugin>),
}

/// A parsed scene document: its version and its top-level plug-ins in order.
#[derive(Debug)]
pub struct SceneXml {
    /// `<scene version>`.
    pub version: String,
    /// Top-level elements (includes expanded, `<default>` consumed).
    pub items: Vec<Rc<Plugin>>,
}

struct Parser {
    defaults: HashMap<String, String>,
    ids: HashMap<String, Rc<Plugin>>,
    items: Vec<Rc<Plugin>>,
    version: String,
}

/// Reads a scene file (and what it includes).
pub fn parse_file(path: &Path) -> Result<SceneXml> {
    let mut p = Parser { defaults: HashMap::new(), ids: HashMap::new(), items: Vec::new(), version: String::new() };
    p.file(path, 0, None)?;
    Ok(SceneXml { version: p.version, items: p.items })
}

/// Parses scene XML text as if it were the file `path` (fuzzing, tests).
pub fn parse_text(text: &str, path: &Path) -> Result<SceneXml> {
    let mut p = Parser { defaults: HashMap::new(), ids: HashMap::new(), items: Vec::new(), version: String::new() };
    p.text(text, path, 0)?;
    Ok(SceneXml { version: p.version, items: p.items })
}

fn line_of(doc: &roxmltree::Document, node: roxmltree::Node) -> u32 {
    doc.text_pos_at(node.range().start).row
}

impl Parser {
    fn file(&mut self, path: &Path, depth: usize, from: Option<&Loc>) -> Result<()> {
        let text = std::fs::read_to_string(path).map_err(|e| match from {
            Some(l) => anyhow!("{l}: <include>: cannot read {}: {e}", path.display()),
            None => anyhow!("{}: cannot read scene file: {e}", path.display()),
        })?;
        self.text(&text, path, depth)
    }

    fn text(&mut self, text: &str, path: &Path, depth: usize) -> Result<()> {
        let file = Rc::new(path.to_path_buf());
        let doc = roxmltree::Document::parse(text).map_err(|e| anyhow!("{}: XML syntax error: {e}", path.display()))?;
        let root = doc.root_element();
        let loc = |n: roxmltree::Node| Loc { file: file.clone(), line: line_of(&doc, n) };
        if root.tag_name().name() != "scene" {
            bail!("{}: the root element must be <scene>, got <{}>", loc(root), root.tag_name().name());
        }
        for a in root.attributes() {
            if a.name() != "version" {
                bail!("{}: <scene>: unknown attribute `{}`", loc(root), a.name());
            }
        }
        let version = root.attribute("version").ok_or_else(|| anyhow!("{}: <scene> needs a `version` attribute", loc(root)))?;
        let major: u32 = version.split('.').next().and_then(|m| m.trim().parse().ok()).unwrap_or(0);
        if major < 2 {
            bail!(
                "{}: <scene version=\"{version}\">: photonlab reads the Mitsuba 2/3 format (version 2.0.0 or later); \
                 convert older scenes with Mitsuba's upgrade tool",
                loc(root)
            );
        }
        if depth == 0 {
            self.version = version.to_string();
        }
        for node in root.children().filter(|n| n.is_element()) {
            let l = loc(node);
            match node.tag_name().name() {
                "default" => {
                    self.check_attrs(node, &l, &["name", "value"])?;
                    let name = node.attribute("name").ok_or_else(|| anyhow!("{l}: <default> needs `name`"))?;
                    let value = node.attribute("value").ok_or_else(|| anyhow!("{l}: <default name=\"{name}\"> needs `value`"))?;
                    // Mitsuba: a value given earlier (or on the command line) wins.
                    self.defaults.entry(name.to_string()).or_insert_with(|| value.to_string());
                }
                "include" => {
                    self.check_attrs(node, &l, &["filename"])?;
                    let name = self.attr(node, "filename", &l)?.ok_or_else(|| anyhow!("{l}: <include> needs `filename`"))?;
                    if depth + 1 > MAX_INCLUDE_DEPTH {
                        bail!("{l}: <include filename=\"{name}\">: includes nested deeper than {MAX_INCLUDE_DEPTH} (a cycle?)");
                    }
                    let p = l.resolve(&name);
                    self.file(&p, depth + 1, Some(&l))?;
                }
                "sensor" | "integrator" | "shape" | "emitter" | "bsdf" | "texture" => {
                    let plugin = Rc::new(self.plugin(&doc, node, &file)?);
                    if let Some(id) = &plugin.id {
                        self.ids.insert(id.clone(), plugin.clone());
                    }
                    self.items.push(plugin);
                }
                "ref" => bail!("{l}: <ref> is allowed only inside a plug-in"),
                other => bail!(
                    "{l}: <{other}> is not supported by photonlab (elements: sensor, integrator, shape, emitter, bsdf, texture, default, include)"
                ),
            }
        }
        Ok(())
    }

    fn check_attrs(&self, node: roxmltree::Node, l: &Loc, allowed: &[&str]) -> Result<()> {
        for a in node.attributes() {
            if !allowed.contains(&a.name()) {
                bail!("{l}: <{}>: unknown attribute `{}`", node.tag_name().name(), a.name());
            }
        }
        Ok(())
    }

    /// An attribute with `$name` parameters substituted.
    fn attr(&self, node: roxmltree::Node, name: &str, l: &Loc) -> Result<Option<String>> {
        let Some(v) = node.attribute(name) else { return Ok(None) };
        if !v.contains('$') {
            return Ok(Some(v.to_string()));
        }
        let mut out = String::with_capacity(v.len());
        let mut rest = v;
        while let Some(i) = rest.find('$') {
            out.push_str(&rest[..i]);
            let after = &rest[i + 1..];
            let end = after.find(|c: char| !(c.is_ascii_alphanumeric() || c == '_')).unwrap_or(after.len());
            let key = &after[..end];
            if key.is_empty() {
                bail!("{l}: attribute `{name}`: `$` without a parameter name in `{v}`");
            }
            let val =
                self.defaults.get(key).ok_or_else(|| anyhow!("{l}: attribute `{name}`: parameter `${key}` has no <default> value"))?;
            out.push_str(val);
            rest = &after[end..];
        }
        out.push_str(rest);
        Ok(Some(out))
    }

    fn plugin(&self, doc: &roxmltree::Document, node: roxmltree::Node, file: &Rc<PathBuf>) -> Result<Plugin> {
        let l = Loc { file: file.clone(), line: line_of(doc, node) };
        let tag = node.tag_name().name().to_string();
        self.check_attrs(node, &l, &["type", "id", "name"])?;
        let ty = self.attr(node, "type", &l)?.ok_or_else(|| anyhow!("{l}: <{tag}> needs a `type` attribute"))?;
        let id = self.attr(node, "id", &l)?;
        let mut props = Vec::new();
        for c in node.children().filter(|n| n.is_element()) {
            let cl = Loc { file: file.clone(), line: line_of(doc, c) };
            let ctag = c.tag_name().name();
            let name = self.attr(c, "name", &cl)?.unwrap_or_default();
            let value = match ctag {
                "bsdf" | "texture" | "emitter" | "film" | "rfilter" | "sampler" | "shape" | "sensor" | "integrator" | "medium"
                | "phase" | "volume" => Value::Plugin(Rc::new(self.plugin(doc, c, file)?)),
                "ref" => {
                    self.check_attrs(c, &cl, &["id", "name"])?;
                    let id = self.attr(c, "id", &cl)?.ok_or_else(|| anyhow!("{cl}: <ref> needs an `id`"))?;
                    let target =
                        self.ids.get(&id).ok_or_else(|| anyhow!("{cl}: <ref id=\"{id}\">: no plug-in with this id was declared before"))?;
                    Value::Plugin(target.clone())
                }
                "transform" => {
                    self.check_attrs(c, &cl, &["name"])?;
                    Value::Transform(self.transform(doc, c, file)?)
                }
                _ => {
                    let v = self.property(c, ctag, &cl)?;
                    if name.is_empty() {
                        bail!("{cl}: <{ctag}> needs a `name`");
                    }
                    v
                }
            };
            if props.iter().any(|p: &Prop| !name.is_empty() && p.name == name) {
                bail!("{cl}: {}: parameter `{name}` is given twice", format_args!("<{tag} type=\"{ty}\">"));
            }
            props.push(Prop { name, value, loc: cl, used: Cell::new(false) });
        }
        Ok(Plugin { tag, ty, id, loc: l, props })
    }

    fn property(&self, c: roxmltree::Node, ctag: &str, cl: &Loc) -> Result<Value> {
        let value = |n: &str| -> Result<String> { self.attr(c, n, cl)?.ok_or_else(|| anyhow!("{cl}: <{ctag}> needs a `{n}` attribute")) };
        let check = |allowed: &[&str]| self.check_attrs(c, cl, allowed);
        Ok(match ctag {
            "float" => {
                check(&["name", "value"])?;
                Value::Float(parse_f64(&value("value")?, cl)?)
            }
            "integer" => {
                check(&["name", "value"])?;
                let v = value("value")?;
                Value::Int(v.trim().parse().map_err(|_| anyhow!("{cl}: <integer>: cannot parse `{v}`"))?)
            }
            "boolean" => {
                check(&["name", "value"])?;
                let v = value("value")?;
                Value::Bool(match v.trim() {
                    "true" => true,
                    "false" => false,
                    _ => bail!("{cl}: <boolean>: value must be `true` or `false`, got `{v}`"),
                })
            }
            "string" => {
                check(&["name", "value"])?;
                Value::Str(value("value")?)
            }
            "rgb" | "spectrum" => {
                check(&["name", "value"])?;
                let v = value("value")?;
                if ctag == "spectrum" && v.contains(':') {
                    bail!(
                        "{cl}: <spectrum value=\"{v}\">: wavelength-value pairs are not supported (photonlab renders RGB; give <rgb> or one value)"
                    );
                }
                let xs = parse_list(&v, cl)?;
                match xs.len() {
                    1 => Value::Rgb(Vec3::splat(xs[0] as f32)),
                    3 if ctag == "rgb" => Value::Rgb(Vec3::new(xs[0] as f32, xs[1] as f32, xs[2] as f32)),
                    n => bail!("{cl}: <{ctag}>: expected {} value(s), got {n}", if ctag == "rgb" { "1 or 3" } else { "1" }),
                }
            }
            "point" | "vector" => {
                check(&["name", "value", "x", "y", "z"])?;
                let v = self.xyz(c, cl, 0.0)?;
                if ctag == "point" { Value::Point(v) } else { Value::Vector(v) }
            }
            other => bail!("{cl}: <{other}> is not a Mitsuba property element"),
        })
    }

    /// `value="x y z"` or `x`/`y`/`z` attributes (missing ones = `default`).
    fn xyz(&self, c: roxmltree::Node, cl: &Loc, default: f64) -> Result<Vec3> {
        let tag = c.tag_name().name();
        if let Some(v) = self.attr(c, "value", cl)? {
            if ["x", "y", "z"].iter().any(|k| c.attribute(*k).is_some()) {
                bail!("{cl}: <{tag}>: give either `value` or `x`/`y`/`z`, not both");
            }
            let xs = parse_list(&v, cl)?;
            return match xs.len() {
                1 => Ok(Vec3::splat(xs[0] as f32)),
                3 => Ok(Vec3::new(xs[0] as f32, xs[1] as f32, xs[2] as f32)),
                n => bail!("{cl}: <{tag}>: `value` needs 1 or 3 numbers, got {n}"),
            };
        }
        let mut out = [default; 3];
        for (k, slot) in ["x", "y", "z"].iter().zip(out.iter_mut()) {
            if let Some(s) = self.attr(c, k, cl)? {
                *slot = parse_f64(&s, cl)?;
            }
        }
        Ok(Vec3::new(out[0] as f32, out[1] as f32, out[2] as f32))
    }

    fn transform(&self, doc: &roxmltree::Document, node: roxmltree::Node, file: &Rc<PathBuf>) -> Result<Mat4> {
        let mut m = Mat4::IDENTITY;
        for c in node.children().filter(|n| n.is_element()) {
            let cl = Loc { file: file.clone(), line: line_of(doc, c) };
            let op = match c.tag_name().name() {
                "translate" => {
                    self.check_attrs(c, &cl, &["value", "x", "y", "z"])?;
                    Mat4::from_translation(self.xyz(c, &cl, 0.0)?)
                }
                "scale" => {
                    self.check_attrs(c, &cl, &["value", "x", "y", "z"])?;
                    let s = self.xyz(c, &cl, 1.0)?;
                    if s.cmpeq(Vec3::ZERO).any() {
                        bail!("{cl}: <scale>: a zero scale is not invertible");
                    }
                    Mat4::from_scale(s)
                }
                "rotate" => {
                    self.check_attrs(c, &cl, &["value", "x", "y", "z", "angle"])?;
                    let axis = self.xyz(c, &cl, 0.0)?;
                    let angle = parse_f64(&self.attr(c, "angle", &cl)?.unwrap_or_else(|| "0".into()), &cl)?;
                    transform::rotate(axis, angle as f32).map_err(|e| anyhow!("{cl}: <rotate>: {e}"))?
                }
                "matrix" => {
                    self.check_attrs(c, &cl, &["value"])?;
                    let v = self.attr(c, "value", &cl)?.ok_or_else(|| anyhow!("{cl}: <matrix> needs `value`"))?;
                    transform::matrix(&parse_list(&v, &cl)?).map_err(|e| anyhow!("{cl}: <matrix>: {e}"))?
                }
                "lookat" => {
                    self.check_attrs(c, &cl, &["origin", "target", "up"])?;
                    let get = |k: &str| -> Result<Option<Vec3>> {
                        let Some(s) = self.attr(c, k, &cl)? else { return Ok(None) };
                        let xs = parse_list(&s, &cl)?;
                        if xs.len() != 3 {
                            bail!("{cl}: <lookat>: `{k}` needs 3 numbers, got {}", xs.len());
                        }
                        Ok(Some(Vec3::new(xs[0] as f32, xs[1] as f32, xs[2] as f32)))
                    };
                    let origin = get("origin")?.ok_or_else(|| anyhow!("{cl}: <lookat> needs `origin`"))?;
                    let target = get("target")?.ok_or_else(|| anyhow!("{cl}: <lookat> needs `target`"))?;
                    transform::look_at(origin, target, get("up")?).map_err(|e| anyhow!("{cl}: <lookat>: {e}"))?
                }
                other => bail!("{cl}: <transform>: <{other}> is not supported (translate, rotate, scale, matrix, lookat)"),
            };
            m = op * m;
        }
        if !m.is_finite() {
            bail!("{}:{}: <transform>: the matrix is not finite", file.display(), line_of(doc, node));
        }
        Ok(m)
    }
}

fn parse_f64(s: &str, l: &Loc) -> Result<f64> {
    let v: f64 = s.trim().parse().map_err(|_| anyhow!("{l}: cannot parse `{s}` as a number"))?;
    if !v.is_finite() {
        bail!("{l}: `{s}` is not a finite number");
    }
    Ok(v)
}

/// Numbers separated by commas and/or white space.
fn parse_list(s: &str, l: &Loc) -> Result<Vec<f64>> {
    s.split(|c: char| c == ',' || c.is_whitespace()).filter(|t| !t.is_empty()).map(|t| parse_f64(t, l)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(s: &str) -> Result<SceneXml> {
        parse_text(s, Path::new("t.xml"))
    }

    #[test]
    fn defaults_refs_and_lines() {
        let x = parse(
            "<scene version=\"3.0.0\">\n<default name=\"r\" value=\"0.25\"/>\n<bsdf type=\"diffuse\" id=\"w\">\n\
             <rgb name=\"reflectance\" value=\"$r, 0.5, 1\"/>\n</bsdf>\n<shape type=\"cube\">\n<ref id=\"w\"/>\n</shape>\n</scene>",
        )
        .unwrap();
        assert_eq!(x.items.len(), 2);
        let shape = &x.items[1];
        assert_eq!(shape.loc.line, 6);
        let b = shape.child("bsdf").unwrap().unwrap();
        match b.spectrum("reflectance").unwrap() {
            Some(SpectrumValue::Rgb(c)) => assert_eq!(c, Vec3::new(0.25, 0.5, 1.0)),
            other => panic!("{other:?}"),
        }
        b.finish().unwrap();
        shape.finish().unwrap();
    }

    #[test]
    fn errors_name_file_line_and_name() {
        let e = parse("<scene version=\"3.0.0\">\n\n<medium type=\"homogeneous\"/></scene>").unwrap_err().to_string();
        assert!(e.starts_with("t.xml:3:") && e.contains("<medium>"), "{e}");
        let e = parse("<scene version=\"3.0.0\"><shape type=\"obj\"><ref id=\"nope\"/></shape></scene>").unwrap_err().to_string();
        assert!(e.contains("nope"), "{e}");
        let e =
            parse("<scene version=\"3.0.0\"><shape type=\"obj\"><float name=\"x\" value=\"$q\"/></shape></scene>").unwrap_err().to_string();
        assert!(e.contains("$q"), "{e}");
        let x =
            parse("<scene version=\"3.0.0\">\n<bsdf type=\"diffuse\">\n<float name=\"roughness\" value=\"1\"/>\n</bsdf></scene>").unwrap();
        let e = x.items[0].finish().unwrap_err().to_string();
        assert!(e.starts_with("t.xml:3:") && e.contains("roughness") && e.contains("<bsdf type=\"diffuse\">"), "{e}");
        assert!(parse("<scene version=\"0.6.0\"></scene>").is_err());
        assert!(parse("<scene><shape/></scene>").is_err());
    }

    #[test]
    fn transform_order_is_left_multiplied() {
        let x = parse(
            "<scene version=\"3.0.0\"><shape type=\"cube\"><transform name=\"to_world\">\
             <scale value=\"2\"/><translate x=\"1\"/></transform></shape></scene>",
        )
        .unwrap();
        let m = x.items[0].transform("to_world").unwrap().unwrap();
        // Scale first, then translate: (1,0,0) -> (2,0,0) -> (3,0,0).
        assert!((m.transform_point3(Vec3::X) - Vec3::new(3.0, 0.0, 0.0)).length() < 1e-6);
    }
}
