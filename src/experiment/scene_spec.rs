//! The scene of an experiment manifest.
//!
//! `scene` is a built-in name, a scene file path (`….toml` or containing `/`,
//! relative to the manifest), a list of those and of tables (the scene becomes the
//! outermost axis), or a `[scene]` table. A table is a scene in the scene contract's
//! keys (`[scene.camera]`, `[[scene.mesh]]`, `[[scene.light]]`), read by the scene
//! loader itself ([`SceneDesc::from_toml`] with [`Dialect::Inline`]), so everything a
//! scene file can say a manifest can say; the loader's module documentation lists the
//! few manifest extensions (a `builtin` / `file` base scene, `fit_height`, `download`).

use crate::scene::Scene;
use crate::scene::loader::{Dialect, SceneBase, SceneDesc, TomlSource, read_scene_file};
use anyhow::{Result, anyhow, bail};
use std::path::Path;
use toml::Spanned;
use toml::de::{DeTable, DeValue};

/// The scene of a manifest (one entry of its `scene` list).
#[derive(Clone, Debug, PartialEq)]
pub struct SceneSpec {
    /// What the manifest says: a base scene and/or inline camera, meshes and lights.
    pub desc: SceneDesc,
    /// `file:line` of the entry, for messages.
    pub at: String,
}

/// Reads the manifest's `scene` value (`text` is the whole manifest; `path` names it
/// in messages; `dir` resolves relative paths).
pub fn parse_scenes(text: &str, path: &Path, dir: &Path) -> Result<Vec<SceneSpec>> {
    let src = TomlSource { file: path, text };
    let doc = DeTable::parse(text).map_err(|e| src.error(&e))?.into_inner();
    let Some((_, value)) = doc.into_iter().find(|(k, _)| k.get_ref() == "scene") else {
        bail!("{}: missing field `scene`", path.display())
    };
    let at = src.line(value.span().start);
    let span = value.span();
    match value.into_inner() {
        DeValue::Array(list) => {
            if list.is_empty() {
                bail!("{at}: scene: empty list");
            }
            let mut specs: Vec<SceneSpec> = Vec::new();
            for x in list {
                let sc = parse_one(x, src, dir)?;
                if specs.iter().any(|o| o.name() == sc.name()) {
                    bail!("{}: scene `{}` is listed twice", sc.at, sc.name());
                }
                specs.push(sc);
            }
            Ok(specs)
        }
        other => Ok(vec![parse_one(Spanned::new(span, other), src, dir)?]),
    }
}

/// One scene: a name, a path or a table.
fn parse_one(v: Spanned<DeValue<'_>>, src: TomlSource, dir: &Path) -> Result<SceneSpec> {
    let at = src.line(v.span().start);
    let desc = match v.get_ref() {
        DeValue::String(s) => {
            let base = if s.ends_with(".toml") || s.contains('/') {
                SceneBase::File(dir.join(s.as_ref()))
            } else {
                SceneBase::builtin(s).map_err(|e| anyhow!("{at}: scene: {e}"))?
            };
            SceneDesc::of_base(base, at.clone())
        }
        DeValue::Table(_) => SceneDesc::from_toml(v, src, dir, Dialect::Inline)?,
        other => bail!("{at}: scene must be a built-in name, a scene file path or a [scene] table, got a {}", other.type_str()),
    };
    Ok(SceneSpec { desc, at })
}

impl SceneSpec {
    /// Short name: the built-in's name, the scene file's stem, or `scene`.
    pub fn name(&self) -> String {
        match &self.desc.base {
            Some(SceneBase::Builtin(b)) => b.clone(),
            Some(SceneBase::File(p)) => p.file_stem().map_or("scene".into(), |s| s.to_string_lossy().into_owned()),
            None => "scene".into(),
        }
    }

    /// One line for the summary: the base scene and what the manifest adds.
    pub fn describe(&self) -> String {
        let d = &self.desc;
        let mut s = match &d.base {
            Some(SceneBase::Builtin(b)) => format!("built-in `{b}`"),
            Some(SceneBase::File(p)) => format!("`{}`", p.display()),
            None => "defined in the manifest".into(),
        };
        if d.base.is_some() {
            let n = |k: usize, what: &str| if k == 0 { String::new() } else { format!(" + {k} {what}(s)") };
            s += &format!(
                "{}{}{}",
                if d.camera.is_some() { " + camera" } else { "" },
                n(d.meshes.len(), "model"),
                n(d.lights.len(), "light")
            );
        }
        s
    }

    /// Checks that every file the scene needs exists (before anything renders).
    pub fn check_files(&self) -> Result<()> {
        let hint =
            |d: &Option<String>| d.as_ref().map(|d| format!(" — download it from {d} (see docs/experiments.md)")).unwrap_or_default();
        if let Some(SceneBase::File(p)) = &self.desc.base {
            if !p.is_file() {
                bail!("{}: scene file {} not found", self.at, p.display());
            }
            // A TOML base file's own models (e.g. public models kept outside the repository).
            let is_toml = p.extension().is_some_and(|e| e.eq_ignore_ascii_case("toml"));
            let meshes = if is_toml { read_scene_file(p)?.meshes } else { Vec::new() };
            for m in &meshes {
                if !m.obj.is_file() {
                    let h = hint(&self.desc.base_download);
                    bail!(
                        "{}: scene file {}: model {} not found{h}; set its path in the scene file's `obj`",
                        self.at,
                        p.display(),
                        m.obj.display()
                    );
                }
            }
        }
        for m in &self.desc.meshes {
            if !m.obj.is_file() {
                let h = hint(&m.download);
                bail!("{}: model {} not found{h}; set its path in `obj`", m.at, m.obj.display());
            }
        }
        Ok(())
    }

    /// Builds the scene; a camera given without a resolution takes `resolution`.
    pub fn load(&self, resolution: [u32; 2]) -> Result<Scene> {
        self.check_files()?;
        self.desc.build("scene", Some(resolution))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::loader::MeshDesc;
    use std::path::PathBuf;

    fn parse(text: &str) -> Result<Vec<SceneSpec>> {
        parse_scenes(text, Path::new("m.toml"), Path::new("dir"))
    }

    #[test]
    fn names_paths_lists_and_tables() {
        let s = parse("scene = \"cornell\"\n").unwrap();
        assert_eq!((s.len(), s[0].name(), s[0].at.as_str()), (1, "cornell".to_string(), "m.toml:1"));
        let s = parse("x = 1\nscene = [\"a/b.toml\", { builtin = \"furnace\" }]\n").unwrap();
        assert_eq!(s[0].desc.base, Some(SceneBase::File(PathBuf::from("dir/a/b.toml"))));
        assert_eq!((s[0].name(), s[1].name()), ("b".to_string(), "furnace".to_string()));
        let s = parse("[scene]\nfile = \"s.toml\"\n[[scene.mesh]]\nobj = \"m.obj\"\nscale = 2\n").unwrap();
        let m: &MeshDesc = &s[0].desc.meshes[0];
        assert_eq!((m.obj.as_path(), m.placement.scale.x, m.at.as_str()), (Path::new("dir/m.obj"), 2.0, "m.toml:3: [[scene.mesh]] 1"));
    }

    #[test]
    fn errors_name_the_line() {
        let e = |t: &str| format!("{:#}", parse(t).unwrap_err());
        let x = e("scene = []\n");
        assert!(x.starts_with("m.toml:1:") && x.contains("empty"), "{x}");
        let x = e("\nscene = [\"cornell\", \"cornell\"]\n");
        assert!(x.starts_with("m.toml:2:") && x.contains("twice"), "{x}");
        let x = e("scene = 3\n");
        assert!(x.starts_with("m.toml:1:") && x.contains("integer"), "{x}");
        let x = e("[scene]\nbuiltin = \"cornell\"\n[[scene.mesh]]\nobj = \"m.obj\"\nat = [0, 0, 0]\n");
        assert!(x.starts_with("m.toml:5:") && x.contains("`at`"), "{x}");
    }

    #[test]
    fn a_missing_model_names_its_line_and_download_hint() {
        let s =
            parse("[scene]\nbuiltin = \"cornell\"\n\n[[scene.mesh]]\nobj = \"nowhere.obj\"\ndownload = \"https://example.org\"\n").unwrap();
        let x = format!("{:#}", s[0].load([8, 8]).unwrap_err());
        assert!(x.starts_with("m.toml:4:") && x.contains("nowhere.obj") && x.contains("https://example.org"), "{x}");
    }

    #[test]
    fn a_scene_files_missing_model_is_found_before_rendering_with_the_entrys_download_hint() {
        let d = tempfile::tempdir().unwrap();
        let scene =
            "[camera]\neye = [0, 1, 4]\nlook_at = [0, 1, 0]\nfov_y_deg = 40\nresolution = [8, 8]\n\n[[mesh]]\nobj = \"absent/model.obj\"\n";
        std::fs::write(d.path().join("s.toml"), scene).unwrap();
        std::fs::write(d.path().join("t.toml"), scene).unwrap();
        let m = "scene = [{ file = \"s.toml\", download = \"https://example.org/models\" }, \"t.toml\"]\n";
        let e = |i: usize| {
            let s = parse_scenes(m, Path::new("m.toml"), d.path()).unwrap();
            format!("{:#}", s[i].check_files().unwrap_err())
        };
        let x = e(0);
        assert!(
            x.starts_with("m.toml:1:") && x.contains("absent/model.obj") && x.contains("download it from https://example.org/models"),
            "{x}"
        );
        // Without a hint the error still names the scene file and the model.
        let x = e(1);
        assert!(x.contains("t.toml") && x.contains("absent/model.obj") && x.contains("not found") && !x.contains("download"), "{x}");
        // `download` needs a `file` base; a scene file may not use it.
        let x = format!("{:#}", parse("[scene]\nbuiltin = \"cornell\"\ndownload = \"x\"\n").unwrap_err());
        assert!(x.starts_with("m.toml:3:") && x.contains("`download`"), "{x}");
    }
}
