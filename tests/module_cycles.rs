//! Import cycles between modules.
//!
//! Reads the `src/` tree from `src/lib.rs` down (following `mod` declarations, so a
//! file only reachable through a `#[cfg(test)]` module is not read), collects every
//! path a file names (`use` trees and inline `crate::`, `self::`, `super::` paths,
//! resolved to the module they point into; comments, string literals and
//! `#[cfg(test)]` items are skipped) and checks two graphs for strongly connected
//! components of more than one node:
//!
//! - the top-level modules: each file or folder directly under `src/` (`accel`,
//!   `scene`, `light`, …) is one node;
//! - the files of `src/accel/`: each file is one node (a plug-in file may use
//!   `wide/`, `wide/` must not use the plug-in files).
//!
//! Cycles that exist today are listed, explicitly, in `ALLOWED_*` below; the test
//! fails on any other cycle and on an allowed one that is gone (so the list always
//! states what is left to fix).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// KNOWN CYCLES between top-level modules, each the sorted members of one strongly
/// connected component (the failure message lists the edges inside it). Empty: the
/// last ones were broken by building samplers and RR policies in their own families
/// (not the registry), moving the gathers under the photon integrator, the render
/// pass into `integrator/`, progress bars into `progress.rs` and the scene
/// fingerprint into `Scene`.
const ALLOWED_TOP_LEVEL_CYCLES: &[&[&str]] = &[];

/// KNOWN CYCLES between the files of `src/accel/` (paths relative to it). Empty.
const ALLOWED_ACCEL_FILE_CYCLES: &[&[&str]] = &[];

// ---------------------------------------------------------------------------
// Lexing: identifiers, `::`, single punctuation; comments and literals dropped.

#[derive(Clone, Debug, PartialEq)]
enum Tok {
    Ident(String),
    PathSep,
    Punct(char),
    Str(String),
}

fn lex(src: &str) -> Vec<(Tok, usize)> {
    let c: Vec<char> = src.chars().collect();
    let mut out = Vec::new();
    let (mut i, mut line) = (0, 1);
    let ident_start = |ch: char| ch.is_alphabetic() || ch == '_';
    let ident_char = |ch: char| ch.is_alphanumeric() || ch == '_';
    while i < c.len() {
        let ch = c[i];
        let next = c.get(i + 1).copied().unwrap_or('\0');
        if ch == '\n' {
            line += 1;
            i += 1;
        } else if ch.is_whitespace() {
            i += 1;
        } else if ch == '/' && next == '/' {
            while i < c.len() && c[i] != '\n' {
                i += 1;
            }
        } else if ch == '/' && next == '*' {
            // Block comments nest.
            let mut depth = 0;
            while i < c.len() {
                if c[i] == '/' && c.get(i + 1) == Some(&'*') {
                    depth += 1;
                    i += 2;
                } else if c[i] == '*' && c.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    line += (c[i] == '\n') as usize;
                    i += 1;
                }
            }
        } else if ch == '"' || ((ch == 'b' || ch == 'c') && next == '"') {
            // Ordinary (byte, C) string with escapes.
            let start_line = line;
            i += if ch == '"' { 1 } else { 2 };
            let mut s = String::new();
            while i < c.len() && c[i] != '"' {
                if c[i] == '\\' {
                    s.push(c[i]);
                    i += 1;
                }
                line += (c[i] == '\n') as usize;
                s.push(c[i]);
                i += 1;
            }
            i += 1;
            out.push((Tok::Str(s), start_line));
        } else if (ch == 'r' && (next == '"' || next == '#')) || (ch == 'b' && next == 'r' && matches!(c.get(i + 2), Some('"' | '#'))) {
            // Raw string r#"…"# (or a raw identifier r#name).
            let mut j = i + if ch == 'b' { 2 } else { 1 };
            let mut hashes = 0;
            while j < c.len() && c[j] == '#' {
                hashes += 1;
                j += 1;
            }
            if c.get(j) != Some(&'"') {
                // Raw identifier.
                let s = j;
                while j < c.len() && ident_char(c[j]) {
                    j += 1;
                }
                out.push((Tok::Ident(c[s..j].iter().collect()), line));
                i = j;
                continue;
            }
            let start_line = line;
            j += 1;
            let s = j;
            loop {
                if j >= c.len() {
                    break;
                }
                if c[j] == '"' && (0..hashes).all(|k| c.get(j + 1 + k) == Some(&'#')) {
                    break;
                }
                line += (c[j] == '\n') as usize;
                j += 1;
            }
            out.push((Tok::Str(c[s..j.min(c.len())].iter().collect()), start_line));
            i = j + 1 + hashes;
        } else if ch == '\'' {
            // Char literal or lifetime.
            if next == '\\' {
                // Skip the quote, the backslash and the escaped character.
                i += 3;
                while i < c.len() && c[i] != '\'' {
                    i += 1;
                }
                i += 1;
            } else if c.get(i + 2) == Some(&'\'') {
                i += 3;
            } else {
                i += 1;
                while i < c.len() && ident_char(c[i]) {
                    i += 1;
                }
            }
        } else if ch == 'b' && next == '\'' {
            i += 2;
            while i < c.len() && c[i] != '\'' {
                i += if c[i] == '\\' { 2 } else { 1 };
            }
            i += 1;
        } else if ident_start(ch) {
            let s = i;
            while i < c.len() && ident_char(c[i]) {
                i += 1;
            }
            out.push((Tok::Ident(c[s..i].iter().collect()), line));
        } else if ch.is_ascii_digit() {
            while i < c.len() && (ident_char(c[i]) || (c[i] == '.' && c.get(i + 1).is_some_and(|d| d.is_ascii_digit()))) {
                i += 1;
            }
        } else if ch == ':' && next == ':' {
            out.push((Tok::PathSep, line));
            i += 2;
        } else {
            out.push((Tok::Punct(ch), line));
            i += 1;
        }
    }
    out
}

// ---------------------------------------------------------------------------
// Parsing one file: its child module declarations, inline modules, and the paths
// it names.

/// A path named in a file: the module scope it appears in, its segments, where.
#[derive(Clone, Debug)]
struct Ref {
    scope: Vec<String>,
    segs: Vec<String>,
    line: usize,
}

#[derive(Default, Debug)]
struct Parsed {
    /// `mod name;` declarations: (scope, name, `#[path]` value).
    children: Vec<(Vec<String>, String, Option<String>)>,
    /// Inline `mod name { … }` modules (full module paths).
    inline: Vec<Vec<String>>,
    refs: Vec<Ref>,
}

/// Index after the attribute starting at `i` (`#` `[` … `]`).
fn attr_end(t: &[(Tok, usize)], i: usize) -> usize {
    let mut depth = 0;
    let mut j = i + 1;
    while j < t.len() {
        match t[j].0 {
            Tok::Punct('[') => depth += 1,
            Tok::Punct(']') => {
                depth -= 1;
                if depth == 0 {
                    return j + 1;
                }
            }
            _ => {}
        }
        j += 1;
    }
    j
}

/// Index after the item starting at `i`: through its first `;` outside brackets, or
/// through the closing brace of its first top-level block.
fn item_end(t: &[(Tok, usize)], mut i: usize) -> usize {
    let mut depth = 0i32;
    while i < t.len() {
        match t[i].0 {
            Tok::Punct('(' | '[' | '{') => depth += 1,
            Tok::Punct(')' | ']') => depth -= 1,
            Tok::Punct('}') => {
                depth -= 1;
                if depth == 0 {
                    return i + 1;
                }
            }
            Tok::Punct(';') if depth == 0 => return i + 1,
            _ => {}
        }
        i += 1;
    }
    i
}

/// Expands the use tree starting at `i` into full paths; returns the index after it.
fn use_tree(t: &[(Tok, usize)], mut i: usize, prefix: &[String], out: &mut Vec<Vec<String>>) -> usize {
    let mut path = prefix.to_vec();
    if matches!(t.get(i), Some((Tok::PathSep, _))) {
        i += 1; // leading `::`
    }
    loop {
        match t.get(i).map(|x| &x.0) {
            Some(Tok::Ident(s)) if s == "self" && !path.is_empty() => i += 1,
            Some(Tok::Ident(s)) => {
                path.push(s.clone());
                i += 1;
            }
            Some(Tok::Punct('$')) => i += 1,
            Some(Tok::Punct('*')) => i += 1,
            Some(Tok::Punct('{')) => {
                i += 1;
                loop {
                    match t.get(i).map(|x| &x.0) {
                        Some(Tok::Punct('}')) => return i + 1,
                        Some(Tok::Punct(',')) => i += 1,
                        None => return i,
                        _ => i = use_tree(t, i, &path, out),
                    }
                }
            }
            _ => break,
        }
        match t.get(i).map(|x| &x.0) {
            Some(Tok::PathSep) => i += 1,
            Some(Tok::Ident(s)) if s == "as" => {
                i += 2;
                break;
            }
            _ => break,
        }
    }
    if !path.is_empty() {
        out.push(path);
    }
    i
}

fn parse(src: &str, module: &[String]) -> Parsed {
    let t = lex(src);
    let mut p = Parsed::default();
    // Inline module scopes: (name, brace depth inside it).
    let mut scopes: Vec<(String, i32)> = Vec::new();
    let mut depth = 0i32;
    let (mut test_item, mut path_attr) = (false, None);
    let scope = |scopes: &[(String, i32)]| -> Vec<String> { module.iter().cloned().chain(scopes.iter().map(|s| s.0.clone())).collect() };
    let mut i = 0;
    while i < t.len() {
        match &t[i].0 {
            Tok::Punct('#') if matches!(t.get(i + 1), Some((Tok::Punct('[' | '!'), _))) => {
                let end = attr_end(&t, i);
                let body: Vec<&Tok> = t[i..end].iter().map(|x| &x.0).collect();
                let cfg_test = [Tok::Ident("cfg".into()), Tok::Punct('('), Tok::Ident("test".into()), Tok::Punct(')'), Tok::Punct(']')];
                if body.len() == 7 && body[2..].iter().zip(&cfg_test).all(|(a, b)| *a == b) {
                    test_item = true;
                }
                if let (Some(Tok::Ident(k)), Some(Tok::Punct('=')), Some(Tok::Str(v))) = (body.get(2), body.get(3), body.get(4))
                    && k == "path"
                {
                    path_attr = Some(v.clone());
                }
                i = end;
                continue;
            }
            _ if test_item => {
                i = item_end(&t, i);
                (test_item, path_attr) = (false, None);
                continue;
            }
            Tok::Ident(k) if k == "mod" => {
                if let Some((Tok::Ident(name), _)) = t.get(i + 1) {
                    match t.get(i + 2).map(|x| &x.0) {
                        Some(Tok::Punct(';')) => {
                            p.children.push((scope(&scopes), name.clone(), path_attr.take()));
                            i += 3;
                            continue;
                        }
                        Some(Tok::Punct('{')) => {
                            depth += 1;
                            scopes.push((name.clone(), depth));
                            p.inline.push(scope(&scopes));
                            i += 3;
                            continue;
                        }
                        _ => {}
                    }
                }
            }
            Tok::Ident(k) if k == "use" => {
                let mut paths = Vec::new();
                let end = use_tree(&t, i + 1, &[], &mut paths);
                for segs in paths {
                    p.refs.push(Ref { scope: scope(&scopes), segs, line: t[i].1 });
                }
                i = end;
                continue;
            }
            Tok::Ident(first) if !(i > 0 && t[i - 1].0 == Tok::PathSep) && matches!(t.get(i + 1), Some((Tok::PathSep, _))) => {
                let mut segs = vec![first.clone()];
                let mut j = i + 1;
                while let (Some((Tok::PathSep, _)), Some((Tok::Ident(s), _))) = (t.get(j), t.get(j + 1)) {
                    segs.push(s.clone());
                    j += 2;
                }
                p.refs.push(Ref { scope: scope(&scopes), segs, line: t[i].1 });
                i = j;
                continue;
            }
            Tok::Punct('{') => {
                depth += 1;
                path_attr = None;
            }
            Tok::Punct('}') => {
                if scopes.last().is_some_and(|s| s.1 == depth) {
                    scopes.pop();
                }
                depth -= 1;
                path_attr = None;
            }
            Tok::Punct(';') => path_attr = None,
            _ => {}
        }
        i += 1;
    }
    p
}

// ---------------------------------------------------------------------------
// The crate: module tree, resolved references, graphs.

/// Every module of the crate with the file that holds it, and every reference.
struct Crate {
    /// Module path → file (relative to `src/`), for file and inline modules.
    modules: BTreeMap<Vec<String>, String>,
    /// (file, reference).
    refs: Vec<(String, Ref)>,
}

/// Reads the crate from `lib.rs` through `mod` declarations; `read` gives a file's
/// text by its path relative to `src/`, or `None`.
fn load(read: &dyn Fn(&str) -> Option<String>) -> Crate {
    let mut c = Crate { modules: BTreeMap::new(), refs: Vec::new() };
    let mut todo = vec![(Vec::<String>::new(), "lib.rs".to_string())];
    while let Some((module, file)) = todo.pop() {
        let src = read(&file).unwrap_or_else(|| panic!("src/{file}: cannot read"));
        c.modules.insert(module.clone(), file.clone());
        let p = parse(&src, &module);
        for m in p.inline {
            c.modules.insert(m, file.clone());
        }
        // Directory for children declared at the file level: `a/b.rs` → `a/b/`,
        // `a/mod.rs` and `lib.rs` → `a/`.
        let dir = match file.strip_suffix("mod.rs").or_else(|| file.strip_suffix("lib.rs")) {
            Some(d) => d.to_string(),
            None => format!("{}/", file.trim_end_matches(".rs")),
        };
        for (scope, name, path) in p.children {
            let inline: Vec<String> = scope[module.len()..].to_vec();
            let mut child = scope.clone();
            child.push(name.clone());
            let f = if let Some(path) = path {
                let here = Path::new(&file).parent().unwrap_or(Path::new(""));
                here.join(path).to_string_lossy().into_owned()
            } else {
                let base = format!("{dir}{}", inline.iter().map(|s| format!("{s}/")).collect::<String>());
                let a = format!("{base}{name}.rs");
                if read(&a).is_some() { a } else { format!("{base}{name}/mod.rs") }
            };
            todo.push((child, f));
        }
        c.refs.extend(p.refs.into_iter().map(|r| (file.clone(), r)));
    }
    c
}

impl Crate {
    /// The module path a reference points into (its items' segments included), or
    /// `None` for paths outside the crate.
    fn resolve(&self, r: &Ref) -> Option<Vec<String>> {
        let mut segs = r.segs.iter().map(|s| s.trim_start_matches('$').to_string()).peekable();
        let mut base: Vec<String> = match segs.peek().map(String::as_str) {
            Some("crate") => {
                segs.next();
                Vec::new()
            }
            Some("self") => {
                segs.next();
                r.scope.clone()
            }
            Some("super") => {
                let mut b = r.scope.clone();
                while segs.peek().map(String::as_str) == Some("super") {
                    segs.next();
                    b.pop();
                }
                b
            }
            // A child module of the scope (`use child::Item`, `child::f()`).
            Some(first) => {
                let mut m = r.scope.clone();
                m.push(first.to_string());
                if !self.modules.contains_key(&m) {
                    return None;
                }
                r.scope.clone()
            }
            None => return None,
        };
        base.extend(segs);
        Some(base)
    }

    /// The file holding the longest module prefix of `path`.
    fn file_of(&self, path: &[String]) -> &str {
        (0..=path.len()).rev().find_map(|n| self.modules.get(&path[..n])).map(String::as_str).unwrap_or("lib.rs")
    }

    /// Edges of the graph whose nodes `node` gives for a file (None: not in this
    /// graph), with the first place each edge is made.
    fn graph(&self, node: &dyn Fn(&str) -> Option<String>) -> BTreeMap<(String, String), String> {
        let mut edges = BTreeMap::new();
        for (file, r) in &self.refs {
            let (Some(from), Some(target)) = (node(file), self.resolve(r)) else { continue };
            let Some(to) = node(self.file_of(&target)) else { continue };
            if from != to {
                let what = format!("src/{file}:{} `{}`", r.line, r.segs.join("::"));
                edges.entry((from, to)).or_insert(what);
            }
        }
        edges
    }
}

/// Strongly connected components of more than one node (Tarjan), each sorted.
fn cycles(edges: &BTreeMap<(String, String), String>) -> Vec<Vec<String>> {
    let nodes: BTreeSet<&String> = edges.keys().flat_map(|(a, b)| [a, b]).collect();
    let nodes: Vec<&String> = nodes.into_iter().collect();
    let idx = |n: &String| nodes.iter().position(|m| *m == n).unwrap();
    let mut adj = vec![Vec::new(); nodes.len()];
    for (a, b) in edges.keys() {
        adj[idx(a)].push(idx(b));
    }
    struct T<'a> {
        adj: &'a [Vec<usize>],
        index: Vec<Option<usize>>,
        low: Vec<usize>,
        on: Vec<bool>,
        stack: Vec<usize>,
        next: usize,
        out: Vec<Vec<usize>>,
    }
    fn visit(t: &mut T, v: usize) {
        t.index[v] = Some(t.next);
        t.low[v] = t.next;
        t.next += 1;
        t.stack.push(v);
        t.on[v] = true;
        for k in 0..t.adj[v].len() {
            let w = t.adj[v][k];
            match t.index[w] {
                None => {
                    visit(t, w);
                    t.low[v] = t.low[v].min(t.low[w]);
                }
                Some(iw) if t.on[w] => t.low[v] = t.low[v].min(iw),
                _ => {}
            }
        }
        if Some(t.low[v]) == t.index[v] {
            let mut comp = Vec::new();
            while let Some(w) = t.stack.pop() {
                t.on[w] = false;
                comp.push(w);
                if w == v {
                    break;
                }
            }
            t.out.push(comp);
        }
    }
    let n = nodes.len();
    let mut t = T { adj: &adj, index: vec![None; n], low: vec![0; n], on: vec![false; n], stack: Vec::new(), next: 0, out: Vec::new() };
    for v in 0..n {
        if t.index[v].is_none() {
            visit(&mut t, v);
        }
    }
    let mut out: Vec<Vec<String>> = t
        .out
        .into_iter()
        .filter(|c| c.len() > 1)
        .map(|c| {
            let mut c: Vec<String> = c.into_iter().map(|i| nodes[i].clone()).collect();
            c.sort();
            c
        })
        .collect();
    out.sort();
    out
}

/// Compares the cycles found with the allowed ones; the problems, explained.
fn check(name: &str, edges: &BTreeMap<(String, String), String>, allowed: &[&[&str]]) -> Vec<String> {
    let found = cycles(edges);
    let allowed: Vec<Vec<String>> = allowed.iter().map(|c| c.iter().map(|s| s.to_string()).collect()).collect();
    let mut problems = Vec::new();
    for c in &found {
        if !allowed.contains(c) {
            let inside: Vec<String> = edges
                .iter()
                .filter(|((a, b), _)| c.contains(a) && c.contains(b))
                .map(|((a, b), w)| format!("    {a} → {b}  ({w})"))
                .collect();
            problems.push(format!("{name}: cycle {c:?}, not in the allow-list:\n{}", inside.join("\n")));
        }
    }
    for c in &allowed {
        if !found.contains(c) {
            problems.push(format!("{name}: allowed cycle {c:?} no longer exists: remove it from the allow-list (found now: {found:?})"));
        }
    }
    problems
}

fn top_level(file: &str) -> Option<String> {
    let first = file.split('/').next()?;
    (first != "lib.rs" && first != "main.rs").then(|| first.trim_end_matches(".rs").to_string())
}

fn accel_file(file: &str) -> Option<String> {
    file.strip_prefix("accel/").map(str::to_string)
}

fn read_src(rel: &str) -> Option<String> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("src");
    std::fs::read_to_string(root.join(rel)).ok()
}

#[test]
fn no_module_cycles_beyond_the_allow_list() {
    let c = load(&read_src);
    assert!(c.modules.len() > 50, "only {} modules read", c.modules.len());
    let mut problems = check("top-level modules", &c.graph(&top_level), ALLOWED_TOP_LEVEL_CYCLES);
    problems.extend(check("files of src/accel", &c.graph(&accel_file), ALLOWED_ACCEL_FILE_CYCLES));
    assert!(problems.is_empty(), "\n{}", problems.join("\n"));
}

/// `wide/` is the engine of the wide-BVH plug-ins and never names them.
#[test]
fn wide_bvh_does_not_use_its_plug_ins() {
    let c = load(&read_src);
    let edges = c.graph(&accel_file);
    assert!(edges.keys().any(|(a, b)| a == "bvh8q.rs" && b == "wide/mod.rs"), "the plug-ins' edges are seen");
    let plug_ins = ["bvh4.rs", "bvh8.rs", "bvh8q.rs"];
    let bad: Vec<_> = edges.iter().filter(|((a, b), _)| a.starts_with("wide/") && plug_ins.contains(&b.as_str())).collect();
    assert!(bad.is_empty(), "{bad:?}");
}

/// The checker on a small made-up crate: it finds a planted cycle through `use`
/// trees, inline paths and `super::`, and ignores comments, strings and
/// `#[cfg(test)]` items.
#[test]
fn checker_finds_planted_cycles_and_ignores_tests_and_comments() {
    let files: BTreeMap<&str, &str> = BTreeMap::from([
        ("lib.rs", "pub mod a;\npub mod b;\npub mod c;\npub mod d;\n"),
        ("a/mod.rs", "mod inner;\nuse crate::{b::{self, X}, c};\npub struct A;\n"),
        ("a/inner.rs", "pub fn f() { super::super::d::g(); }\n"),
        ("b.rs", "pub fn h() -> crate::a::A { crate::a::A }\npub struct X;\n"),
        (
            "c.rs",
            "// use crate::d;\n/* crate::d::g() */\nconst S: &str = \"crate::d::g\";\n#[cfg(test)]\nmod tests { use crate::d; }\n#[cfg(test)]\n#[path = \"t.rs\"]\nmod t;\n",
        ),
        ("d.rs", "pub fn g() { let c = 'c'; let _: &'static str = r#\"crate::c\"#; }\n#[cfg(test)]\nfn t() { crate::c::x(); }\n"),
    ]);
    let read = |p: &str| files.get(p).map(|s| s.to_string());
    let c = load(&read);
    let edges = c.graph(&top_level);
    let pairs: Vec<(String, String)> = edges.keys().cloned().collect();
    let want = [("a", "b"), ("a", "c"), ("a", "d"), ("b", "a")].map(|(x, y)| (x.to_string(), y.to_string()));
    assert_eq!(pairs, want);
    assert_eq!(cycles(&edges), vec![vec!["a".to_string(), "b".to_string()]]);
    assert_eq!(check("t", &edges, &[]).len(), 1);
    assert!(check("t", &edges, &[&["a", "b"]]).is_empty());
    assert_eq!(check("t", &edges, &[&["a", "b"], &["c", "d"]]).len(), 1, "a stale entry is reported");
}
