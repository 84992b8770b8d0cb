//! The value types a parameter can have, read from TOML (manifests) or from text
//! (command line, declared defaults).

use toml::Value;

/// A type a parameter can have.
pub trait ParamValue: Sized {
    /// Type name in the docs.
    const TYPE: &'static str;
    /// `--key` alone means `--key true`.
    const FLAG: bool = false;
    /// From a TOML value (checking range).
    fn from_toml(v: &Value) -> anyhow::Result<Self>;
    /// From command-line text.
    fn from_text(s: &str) -> anyhow::Result<Self>;
    /// As TOML; `None` for an unset optional (`auto`).
    fn to_toml(&self) -> Option<Value>;
    /// Checks a TOML value.
    fn check(v: &Value) -> anyhow::Result<()> {
        Self::from_toml(v).map(|_| ())
    }
    /// Command-line text as TOML (`None`: the key is unset, i.e. `auto`).
    fn parse_text(s: &str) -> anyhow::Result<Option<Value>> {
        Self::from_text(s).map(|x| x.to_toml())
    }
}

fn kind(v: &Value) -> &'static str {
    v.type_str()
}

fn int(v: &Value) -> anyhow::Result<i64> {
    v.as_integer().ok_or_else(|| anyhow::anyhow!("expected a whole number, found {}", kind(v)))
}

macro_rules! unsigned {
    ($t:ty) => {
        impl ParamValue for $t {
            const TYPE: &'static str = "integer";
            fn from_toml(v: &Value) -> anyhow::Result<Self> {
                let i = int(v)?;
                <$t>::try_from(i).map_err(|_| anyhow::anyhow!("{i} is out of range (0 ..= {})", <$t>::MAX))
            }
            fn from_text(s: &str) -> anyhow::Result<Self> {
                s.trim().replace('_', "").parse::<$t>().map_err(|_| anyhow::anyhow!("`{s}` is not a whole number ≥ 0"))
            }
            fn to_toml(&self) -> Option<Value> {
                i64::try_from(*self).ok().map(Value::Integer)
            }
        }
    };
}
unsigned!(u32);
unsigned!(u64);
unsigned!(usize);

macro_rules! float {
    ($t:ty) => {
        impl ParamValue for $t {
            const TYPE: &'static str = "float";
            fn from_toml(v: &Value) -> anyhow::Result<Self> {
                match v {
                    Value::Float(f) => Ok(*f as $t),
                    Value::Integer(i) => Ok(*i as $t),
                    _ => Err(anyhow::anyhow!("expected a number, found {}", kind(v))),
                }
            }
            /// A number, or a fraction `A/B` (computed in this type).
            fn from_text(s: &str) -> anyhow::Result<Self> {
                let num = |t: &str| t.trim().parse::<$t>().map_err(|_| anyhow::anyhow!("`{s}` is not a number"));
                match s.split_once('/') {
                    Some((a, b)) => Ok(num(a)? / num(b)?),
                    None => num(s),
                }
            }
            fn to_toml(&self) -> Option<Value> {
                Some(Value::Float(*self as f64))
            }
        }
    };
}
float!(f32);
float!(f64);

impl ParamValue for bool {
    const TYPE: &'static str = "bool";
    const FLAG: bool = true;
    fn from_toml(v: &Value) -> anyhow::Result<Self> {
        v.as_bool().ok_or_else(|| anyhow::anyhow!("expected true or false, found {}", kind(v)))
    }
    fn from_text(s: &str) -> anyhow::Result<Self> {
        match s.trim() {
            "true" => Ok(true),
            "false" => Ok(false),
            _ => Err(anyhow::anyhow!("`{s}` is not true or false")),
        }
    }
    fn to_toml(&self) -> Option<Value> {
        Some(Value::Boolean(*self))
    }
}

impl ParamValue for String {
    const TYPE: &'static str = "string";
    fn from_toml(v: &Value) -> anyhow::Result<Self> {
        v.as_str().map(str::to_string).ok_or_else(|| anyhow::anyhow!("expected a string, found {}", kind(v)))
    }
    fn from_text(s: &str) -> anyhow::Result<Self> {
        Ok(s.to_string())
    }
    fn to_toml(&self) -> Option<Value> {
        Some(Value::String(self.clone()))
    }
}

/// `auto` (or `none`) on the command line leaves an optional parameter unset.
impl<T: ParamValue> ParamValue for Option<T> {
    const TYPE: &'static str = T::TYPE;
    fn from_toml(v: &Value) -> anyhow::Result<Self> {
        T::from_toml(v).map(Some)
    }
    fn from_text(s: &str) -> anyhow::Result<Self> {
        match s.trim() {
            "auto" | "none" => Ok(None),
            t => T::from_text(t).map(Some),
        }
    }
    fn to_toml(&self) -> Option<Value> {
        self.as_ref().and_then(T::to_toml)
    }
}

/// A list: `[1, 4, 16]` in TOML, `1,4,16` on the command line.
impl ParamValue for Vec<u32> {
    const TYPE: &'static str = "list of integers";
    fn from_toml(v: &Value) -> anyhow::Result<Self> {
        let a = v.as_array().ok_or_else(|| anyhow::anyhow!("expected a list, found {}", kind(v)))?;
        a.iter().map(u32::from_toml).collect()
    }
    fn from_text(s: &str) -> anyhow::Result<Self> {
        let t = s.trim().trim_start_matches('[').trim_end_matches(']');
        t.split(',').map(str::trim).filter(|x| !x.is_empty()).map(u32::from_text).collect()
    }
    fn to_toml(&self) -> Option<Value> {
        Some(Value::Array(self.iter().map(|&x| Value::Integer(x as i64)).collect()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_and_toml_agree() {
        assert_eq!(f32::from_text("2/3").unwrap(), 2.0f32 / 3.0);
        assert_eq!(f32::from_toml(&Value::Float(0.3)).unwrap(), 0.3f32);
        assert_eq!(f32::from_toml(&f32::from_text("0.3").unwrap().to_toml().unwrap()).unwrap(), 0.3f32);
        assert!(u32::from_toml(&Value::Integer(-1)).is_err());
        assert!(u32::from_text("1.5").is_err());
        assert_eq!(Option::<f32>::from_text("auto").unwrap(), None);
        assert_eq!(Option::<u64>::parse_text("auto").unwrap(), None);
        assert_eq!(Vec::<u32>::from_text("1, 4,16").unwrap(), vec![1, 4, 16]);
        assert_eq!(Vec::<u32>::from_text("").unwrap(), Vec::<u32>::new());
        assert!(bool::from_text("yes").is_err());
    }
}
