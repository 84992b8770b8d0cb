//! Plug-in parameters. Each plug-in declares its parameters once, next to its code,
//! with [`crate::params!`]: name, type, default and a one-line doc. The declaration
//! gives a typed struct, the table the docs are generated from (`photonlab plugins`)
//! and the reader that takes the values out of a [`Params`] store.
//!
//! Every front end fills the same store: manifests and configuration TOML (keys
//! beside the common ones of [`crate::config::RenderConfig`]), and the command line
//! (`--set key=value`, or `--key value` for any declared key). Plug-ins read their
//! values through a [`Reader`], which remembers what was read, so a key that no chosen
//! plug-in uses is an error naming the key, its owner and the plug-ins chosen
//! (as pbrt-v4 reports unused parameters).

pub mod docs;
mod value;

pub use value::ParamValue;

use anyhow::{Result, anyhow};
use serde::{Deserialize, Serialize};
use std::cell::RefCell;
use std::collections::{BTreeMap, BTreeSet};
use toml::Value;

/// One declared parameter.
#[derive(Clone, Copy, Debug)]
pub struct ParamDef {
    /// Key (snake_case; the command line also takes `--key-with-dashes`).
    pub name: &'static str,
    /// Type as shown in the docs.
    pub ty: &'static str,
    /// Default as text (parsed like a command-line value; `auto` = derived at run time).
    pub default: &'static str,
    /// One-line description.
    pub doc: &'static str,
    /// Checks a TOML value's type and range.
    pub check: fn(&Value) -> anyhow::Result<()>,
    /// Parses a command-line value into TOML (`None`: unset, i.e. `auto`).
    pub parse: fn(&str) -> anyhow::Result<Option<Value>>,
    /// A boolean: `--key` alone means `--key true`.
    pub flag: bool,
}

/// The parameter values a configuration sets (keys beyond the common ones).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Params(pub BTreeMap<String, Value>);

impl Params {
    /// Sets `key` to `value` (no check; readers check types).
    pub fn set(&mut self, key: &str, value: impl Into<Value>) {
        self.0.insert(key.to_string(), value.into());
    }
    /// Removes `key`.
    pub fn remove(&mut self, key: &str) -> Option<Value> {
        self.0.remove(key)
    }
    /// The raw value of `key`, if set.
    pub fn raw(&self, key: &str) -> Option<&Value> {
        self.0.get(key)
    }
    /// Whether `key` is set.
    pub fn contains(&self, key: &str) -> bool {
        self.0.contains_key(key)
    }
}

/// Reads typed values out of a [`Params`] store and remembers which keys were read.
pub struct Reader<'a> {
    params: &'a Params,
    used: RefCell<BTreeSet<String>>,
    chosen: RefCell<Vec<String>>,
}

impl<'a> Reader<'a> {
    /// A reader over `params`.
    pub fn new(params: &'a Params) -> Self {
        Reader { params, used: RefCell::new(BTreeSet::new()), chosen: RefCell::new(Vec::new()) }
    }

    /// The value of `key`, or `default` (declaration text) when unset.
    pub fn get<T: ParamValue>(&self, key: &str, default: &str) -> Result<T> {
        self.used.borrow_mut().insert(key.to_string());
        match self.params.0.get(key) {
            Some(v) => T::from_toml(v).map_err(|e| anyhow!("parameter `{key}`: {e}")),
            None => T::from_text(default).map_err(|e| anyhow!("default of `{key}` (`{default}`): {e}")),
        }
    }

    /// Records that plug-in `what` (e.g. "gather `irradiance_cache`") takes part, for
    /// the unused-key message.
    pub fn chose(&self, what: impl Into<String>) {
        self.chosen.borrow_mut().push(what.into());
    }

    /// The keys nobody read (sorted).
    pub fn unused(&self) -> Vec<String> {
        let used = self.used.borrow();
        self.params.0.keys().filter(|k| !used.contains(*k)).cloned().collect()
    }

    /// The plug-ins recorded with [`Reader::chose`], for messages.
    pub fn chosen(&self) -> String {
        self.chosen.borrow().join(", ")
    }

    /// Fails on the first key nobody read, naming the plug-ins that were chosen and the
    /// plug-in the key belongs to (from `owners`: key → owner description).
    pub fn finish(&self, owner_of: impl Fn(&str) -> Option<String>) -> Result<()> {
        let used = self.used.borrow();
        let Some(key) = self.params.0.keys().find(|k| !used.contains(*k)) else { return Ok(()) };
        let chosen = self.chosen.borrow().join(", ");
        Err(match owner_of(key) {
            Some(owner) => anyhow!("parameter `{key}` belongs to {owner}, which this configuration does not use (chosen: {chosen})"),
            None => anyhow!("unknown parameter `{key}` (chosen: {chosen}; `photonlab plugins` lists every parameter)"),
        })
    }
}

/// Declares a plug-in's parameters: a struct with one field per parameter, its
/// [`ParamDef`] table (`DEFS`) and `read`, which takes the values from a [`Reader`].
/// Defaults are written as command-line text (`"0.3"`, `"cone"`, `"auto"` for an
/// optional value derived at run time) and checked by a unit test of every table.
///
/// ```ignore
/// photonlab::params! {
///     /// Parameters of the `irradiance_cache` gather.
///     pub struct CacheParams {
///         /// Error tolerance a (Ward).
///         ic_tolerance: f32 = "0.3",
///     }
/// }
/// ```
#[macro_export]
macro_rules! params {
    (
        $(#[doc = $sdoc:literal])*
        pub struct $name:ident {
            $(
                $(#[doc = $doc:literal])+
                $field:ident : $ty:ty = $default:literal
            ),* $(,)?
        }
    ) => {
        $(#[doc = $sdoc])*
        #[derive(Clone, Debug, PartialEq)]
        pub struct $name {
            $(
                $(#[doc = $doc])+
                pub $field: $ty,
            )*
        }

        impl $name {
            /// The declared parameters (name, type, default, doc).
            pub const DEFS: &'static [$crate::param::ParamDef] = &[$(
                $crate::param::ParamDef {
                    name: stringify!($field),
                    ty: <$ty as $crate::param::ParamValue>::TYPE,
                    default: $default,
                    doc: concat!($($doc, "\n"),+),
                    check: <$ty as $crate::param::ParamValue>::check,
                    parse: <$ty as $crate::param::ParamValue>::parse_text,
                    flag: <$ty as $crate::param::ParamValue>::FLAG,
                }
            ),*];

            /// Reads the values (defaults where unset) and checks their types.
            pub fn read(r: &$crate::param::Reader) -> ::anyhow::Result<Self> {
                Ok($name { $($field: r.get::<$ty>(stringify!($field), $default)?,)* })
            }
        }

        impl Default for $name {
            fn default() -> Self {
                let p = $crate::param::Params::default();
                Self::read(&$crate::param::Reader::new(&p)).expect("declared defaults parse (checked by the tests of every parameter table)")
            }
        }
    };
}

/// The first line of a doc text, trimmed.
pub fn one_line(doc: &str) -> String {
    let joined: Vec<&str> = doc.lines().map(str::trim).filter(|l| !l.is_empty()).collect();
    joined.join(" ")
}

/// Checks a parameter table: names unique, defaults parse, docs present.
pub fn check_defs(defs: &[ParamDef]) -> anyhow::Result<()> {
    let mut seen = BTreeSet::new();
    for d in defs {
        if !seen.insert(d.name) {
            return Err(anyhow::anyhow!("parameter `{}` declared twice", d.name));
        }
        (d.parse)(d.default).map_err(|e| anyhow::anyhow!("default of `{}`: {e}", d.name))?;
        if one_line(d.doc).is_empty() {
            return Err(anyhow::anyhow!("parameter `{}` has no doc", d.name));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    crate::params! {
        /// Test parameters.
        pub struct TestParams {
            /// A number.
            alpha: f32 = "2/3",
            /// A count.
            n: u32 = "4",
            /// Optional.
            r: Option<f32> = "auto",
            /// A flag.
            on: bool = "true",
            /// A list.
            at: Vec<u32> = "",
            /// A name.
            name: String = "cone",
        }
    }

    #[test]
    fn defaults_and_reads() {
        let d = TestParams::default();
        assert_eq!(d.alpha, 2.0f32 / 3.0);
        assert_eq!((d.n, d.r, d.on, d.at.len(), d.name.as_str()), (4, None, true, 0, "cone"));
        check_defs(TestParams::DEFS).unwrap();
        let mut p = Params::default();
        p.set("n", 7i64);
        p.set("r", 0.5);
        p.set("at", Value::Array(vec![Value::Integer(1), Value::Integer(4)]));
        let r = Reader::new(&p);
        let t = TestParams::read(&r).unwrap();
        assert_eq!((t.n, t.r, t.at.clone()), (7, Some(0.5), vec![1, 4]));
        r.finish(|_| None).unwrap();
    }

    #[test]
    fn wrong_types_and_unused_keys_are_errors() {
        let mut p = Params::default();
        p.set("n", "many");
        let e = TestParams::read(&Reader::new(&p)).unwrap_err().to_string();
        assert!(e.contains("`n`"), "{e}");
        let mut p = Params::default();
        p.set("bogus", 1i64);
        let r = Reader::new(&p);
        r.chose("integrator `path`");
        TestParams::read(&r).unwrap();
        let e = r.finish(|k| (k == "bogus").then(|| "gather `x`".to_string())).unwrap_err().to_string();
        assert!(e.contains("bogus") && e.contains("gather `x`") && e.contains("integrator `path`"), "{e}");
    }
}
