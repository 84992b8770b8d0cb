//! docs/plugins.md is `photonlab plugins --markdown`, every parameter flag works on
//! the command line, the README stays a front page and the docs' links resolve.

use std::process::Command;

fn photonlab(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_photonlab")).args(args).output().expect("run photonlab")
}

/// The text of `file` between `<!-- NAME:begin -->` and `<!-- NAME:end -->` is the
/// output of `photonlab plugins FLAG`.
fn assert_generated_between(file: &str, name: &str, flag: &str) {
    let out = photonlab(&["plugins", flag]);
    assert!(out.status.success());
    let generated = String::from_utf8(out.stdout).unwrap();
    let doc = std::fs::read_to_string(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(file)).unwrap();
    let (begin, end) = (format!("<!-- {name}:begin -->\n"), format!("<!-- {name}:end -->"));
    let a = doc.find(&begin).unwrap_or_else(|| panic!("{file} has the {name}:begin marker")) + begin.len();
    let b = doc.find(&end).unwrap_or_else(|| panic!("{file} has the {name}:end marker"));
    assert!(
        doc[a..b].trim_end() == generated.trim_end(),
        "{file} differs from `photonlab plugins {flag}`: regenerate it with\n  \
         cargo run --release -- plugins {flag}\nand paste it between the {name} markers"
    );
}

#[test]
fn docs_parameter_tables_are_the_generated_ones() {
    assert_generated_between("docs/plugins.md", "plugins", "--markdown");
}

#[test]
fn readme_plugin_table_is_the_generated_one() {
    assert_generated_between("README.md", "glance", "--glance");
}

/// Pages other branches add to docs/ (linked from the README and the index before
/// they land); a link to one of them is only checked once the file exists.
const PAGES_TO_COME: &[&str] = &[];

/// The README is a front page (≤ 300 lines) and every relative link in it and in
/// docs/ points at a file of the repository.
#[test]
fn readme_is_short_and_doc_links_resolve() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    assert!(readme.lines().count() <= 300, "README.md has {} lines (at most 300: the rest belongs in docs/)", readme.lines().count());
    let mut pages = vec![root.join("README.md")];
    for e in std::fs::read_dir(root.join("docs")).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "md") {
            pages.push(p);
        }
    }
    let mut broken = Vec::new();
    for page in &pages {
        let text = std::fs::read_to_string(page).unwrap();
        // Markdown links and images: ](target), outside code spans is good enough here.
        for (i, _) in text.match_indices("](") {
            let rest = &text[i + 2..];
            let Some(end) = rest.find(')') else { continue };
            let target = rest[..end].split('#').next().unwrap_or_default().trim();
            if target.is_empty() || target.contains("://") || target.starts_with("mailto:") || target.contains(' ') {
                continue;
            }
            let path = page.parent().unwrap().join(target);
            let name = path.file_name().and_then(|n| n.to_str()).unwrap_or_default();
            if !path.exists() && !PAGES_TO_COME.contains(&name) {
                broken.push(format!("{}: {target}", page.strip_prefix(root).unwrap().display()));
            }
        }
    }
    assert!(broken.is_empty(), "links to missing files:\n{}", broken.join("\n"));
}

/// Every flag `render` had before parameters moved into the plug-ins still works, as
/// an alias of `--set KEY=VALUE`, with the same value.
#[test]
fn old_flags_are_aliases_of_set() {
    use clap::Parser;
    use photonlab::cli::{Cli, Command, expand_param_flags};
    let old: &[(&str, &str)] = &[
        ("photons", "1234"),
        ("caustic-photons", "55"),
        ("emit-photons", "777"),
        ("max-emitted", "999"),
        ("gather", "final_gather"),
        ("gather-samples", "7"),
        ("gather-bounces", "2"),
        ("precomputed-irradiance", "false"),
        ("precompute-stride", "3"),
        ("k", "11"),
        ("caustic-k", "12"),
        ("max-radius", "0.5"),
        ("caustic-max-radius", "0.25"),
        ("filter", "box"),
        ("disc", "0.75"),
        ("direct-samples", "3"),
        ("direct-sampler", "random"),
        ("ic-tolerance", "0.2"),
        ("ic-min-radius", "0.02"),
        ("ic-max-radius", "0.3"),
        ("ic-min-pixels", "5"),
        ("ic-max-pixels", "50"),
        ("ic-gradients", "false"),
        ("ic-samples", "128"),
        ("ic-neighbor-clamp", "false"),
        ("glossy-samples", "8"),
        ("passes", "5"),
        ("photons-per-pass", "1000"),
        ("alpha", "0.5"),
        ("time-limit", "2.5"),
        ("sppm-radius", "0.1"),
        ("sppm-direct", "photons"),
        ("checkpoint-every", "2"),
    ];
    let config = |args: Vec<String>| {
        let mut argv = vec!["photonlab".to_string(), "render".to_string()];
        argv.extend(args);
        match Cli::parse_from(expand_param_flags(argv)).command {
            Command::Render(a) => a.config().unwrap(),
            _ => unreachable!(),
        }
    };
    for (flag, value) in old {
        let key = flag.replace('-', "_");
        let a = config(vec![format!("--{flag}"), value.to_string()]);
        let b = config(vec![format!("--{flag}={value}")]);
        let c = config(vec!["--set".into(), format!("{key}={value}")]);
        assert!(a.params.contains(&key), "--{flag}: {:?}", a.params);
        assert_eq!(a, b, "--{flag} VALUE vs --{flag}=VALUE");
        assert_eq!(a, c, "--{flag} vs --set {key}=...");
    }
    // `--resume` alone is a flag; with -o the state file goes beside the image.
    let r = config(vec!["--resume".into(), "-o".into(), "out/x.exr".into()]);
    assert_eq!(r.params.raw("resume"), Some(&toml::Value::Boolean(true)));
    assert_eq!(r.params.raw("checkpoint_file").and_then(|v| v.as_str()), Some("out/x.checkpoint.json"));
    // `auto` unsets an optional parameter; wrong types are errors naming the key.
    assert!(!config(vec!["--max-radius".into(), "auto".into()]).params.contains("max_radius"));
    let mut argv: Vec<String> = ["photonlab", "render", "--k", "many"].iter().map(|s| s.to_string()).collect();
    let Command::Render(a) = Cli::parse_from(expand_param_flags(std::mem::take(&mut argv))).command else { unreachable!() };
    assert!(a.config().unwrap_err().to_string().contains("`k`"));
}

/// A render with old-style flags and the same render with `--set` write the same bytes;
/// a parameter of a plug-in that is not chosen fails, naming its owner.
#[test]
fn flags_and_set_render_the_same_image() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let common = ["render", "--quiet", "--resolution", "16x16", "--spp", "1", "--integrator", "photon"];
    let a = dir.join("a.exr");
    let b = dir.join("b.exr");
    let mut args_a: Vec<&str> = common.to_vec();
    args_a.extend([
        "--photons",
        "3000",
        "--caustic-photons",
        "0",
        "--gather",
        "final_gather",
        "--gather-samples",
        "4",
        "-o",
        a.to_str().unwrap(),
    ]);
    assert!(photonlab(&args_a).status.success());
    let mut args_b: Vec<&str> = common.to_vec();
    args_b.extend(["--set", "photons=3000", "--set", "caustic_photons=0", "--set", "gather=final_gather", "--set", "gather_samples=4"]);
    args_b.extend(["-o", b.to_str().unwrap()]);
    assert!(photonlab(&args_b).status.success());
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    let mut bad: Vec<&str> = common.to_vec();
    bad.extend(["--gather", "final_gather", "--ic-tolerance", "0.2", "-o", a.to_str().unwrap()]);
    let out = photonlab(&bad);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("ic_tolerance") && err.contains("irradiance_cache"), "{err}");
}
