//! `photonlab accumulate` on corrupt `.psum` parts: every header field and the sums are
//! checked on read, and a bad part is one `error:` line naming the file and the
//! problem, exit code 1, never a panic or a silently wrapped sum.

use std::path::Path;
use std::process::Command;

const MAGIC_LEN: usize = 16;

fn photonlab(args: &[&str], dir: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_photonlab")).args(args).current_dir(dir).output().expect("run photonlab")
}

/// (magic, header JSON, sums) of a part file.
fn split(bytes: &[u8]) -> (Vec<u8>, serde_json::Value, Vec<u8>) {
    let n = u64::from_le_bytes(bytes[MAGIC_LEN..MAGIC_LEN + 8].try_into().unwrap()) as usize;
    let head = &bytes[MAGIC_LEN + 8..MAGIC_LEN + 8 + n];
    (bytes[..MAGIC_LEN].to_vec(), serde_json::from_slice(head).unwrap(), bytes[MAGIC_LEN + 8 + n..].to_vec())
}

fn join(magic: &[u8], head: &serde_json::Value, sums: &[u8]) -> Vec<u8> {
    let h = serde_json::to_vec(head).unwrap();
    let mut b = magic.to_vec();
    b.extend_from_slice(&(h.len() as u64).to_le_bytes());
    b.extend_from_slice(&h);
    b.extend_from_slice(sums);
    b
}

#[test]
fn corrupt_parts_are_named_errors() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    for (range, out) in [("0..2", "a"), ("2..4", "b")] {
        let o = photonlab(
            &[
                "render",
                "--builtin",
                "cornell",
                "--integrator",
                "path",
                "--spp",
                "4",
                "--resolution",
                "6x4",
                "--quiet",
                "--sample-range",
                range,
                "-o",
                out,
            ],
            d,
        );
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let ok = photonlab(&["accumulate", "whole.exr", "a.psum", "b.psum"], d);
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    let (magic, head, sums) = split(&std::fs::read(d.join("b.psum")).unwrap());
    let with = |k: &str, v: serde_json::Value| {
        let mut h = head.clone();
        h[k] = v;
        h
    };
    // A sum far beyond what two samples can give: two such parts would wrap an i128.
    let mut huge = sums.clone();
    huge[3 * 48..3 * 48 + 16].copy_from_slice(&(i128::MAX / 2 + 1).to_le_bytes());
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("size", join(&magic, &with("width", 0.into()), &sums), "image size 0x4"),
        ("spp", join(&magic, &with("spp", 1_000_000_000u64.into()), &sums), "spp 1000000000"),
        ("range", join(&magic, &with("range", serde_json::json!({"start": 2, "end": 9})), &sums), "sample range 2..9"),
        ("nonfinite", join(&magic, &with("nonfinite_samples", 49.into()), &sums), "nonfinite_samples 49"),
        ("length", join(&magic, &head, &sums[..sums.len() - 48]), "1104 bytes of sums for 6x4 pixels (expected 1152"),
        ("height", join(&magic, &with("height", 5.into()), &sums), "for 6x5 pixels"),
        ("sum", join(&magic, &head, &huge), "pixel (3, 0) channel 0"),
        ("json", join(&magic, &with("range", "2..4".into()), &sums), "header: "),
    ];
    for (name, bytes, want) in cases {
        let file = format!("{name}.psum");
        std::fs::write(d.join(&file), bytes).unwrap();
        let o = photonlab(&["accumulate", "bad.exr", "a.psum", &file], d);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{name}: {err}");
        assert!(!err.contains("panicked"), "{err}");
        let lines: Vec<&str> = err.lines().collect();
        assert_eq!(lines.len(), 1, "{name}: stderr must be one line: {err}");
        assert!(lines[0].starts_with("error: ") && lines[0].contains(&file) && lines[0].contains(want), "{name}: want `{want}`: {err}");
    }
}
