//! The README's parameter section is `photonlab plugins --markdown`, and every
//! parameter flag works on the command line.

use std::process::Command;

fn photonlab(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_photonlab")).args(args).output().expect("run photonlab")
}

#[test]
fn readme_parameter_tables_are_the_generated_ones() {
    let out = photonlab(&["plugins", "--markdown"]);
    assert!(out.status.success());
    let generated = String::from_utf8(out.stdout).unwrap();
    let readme = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/README.md")).unwrap();
    let (begin, end) = ("<!-- plugins:begin -->\n", "<!-- plugins:end -->");
    let a = readme.find(begin).expect("README has the plugins:begin marker") + begin.len();
    let b = readme.find(end).expect("README has the plugins:end marker");
    assert!(
        readme[a..b].trim_end() == generated.trim_end(),
        "README.md's parameter section differs from `photonlab plugins --markdown`: regenerate it with\n  \
         cargo run --release -- plugins --markdown\nand paste it between the markers"
    );
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
