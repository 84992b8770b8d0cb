//! The statistical test suite (`photonlab stats`): evidence that the estimators are
//! right, as hypothesis tests with fixed seeds.
//!
//! Five families, one file each: [`rr`] (Russian roulette is unbiased, Welch's
//! t-test), [`discrepancy`] (L2-star and exact star discrepancy of the samplers),
//! [`chi2`] (chi-square goodness of fit of every sampling routine against its own
//! pdf), [`brdf`] (energy conservation and reciprocity), [`convergence`] (error
//! vs sample count) and [`progressive`] (error vs passes of `sppm` / `ppm`). Every family also runs a *planted control* — a deliberately
//! wrong estimator, pdf or material — whose expected verdict is `fail`, so each test
//! is shown to be able to fail. The suite passes exactly when every verdict equals
//! its expected value.

pub mod brdf;
pub mod chi2;
pub mod convergence;
pub mod discrepancy;
pub mod progressive;
pub mod rr;

use crate::plot::{LinePlot, line_plot};
use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use statrs::distribution::{ContinuousCDF, Normal, StudentsT};
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

/// Which family of tests to run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Family {
    /// Every family.
    All,
    /// Russian roulette is unbiased (Welch's t-test).
    Rr,
    /// Discrepancy of the samplers' point sets.
    Discrepancy,
    /// Chi-square goodness of fit of every sampling routine.
    Chi2,
    /// Energy conservation and reciprocity of the BSDFs.
    Brdf,
    /// Convergence rates (error vs samples / photons).
    Convergence,
    /// Consistency of the progressive integrators (error vs passes).
    Progressive,
}

impl Family {
    /// The single families, in report order.
    pub const EACH: [Family; 6] = [Family::Rr, Family::Discrepancy, Family::Chi2, Family::Brdf, Family::Convergence, Family::Progressive];

    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Family::All => "all",
            Family::Rr => "rr",
            Family::Discrepancy => "discrepancy",
            Family::Chi2 => "chi2",
            Family::Brdf => "brdf",
            Family::Convergence => "convergence",
            Family::Progressive => "progressive",
        }
    }
}

/// Flags of `photonlab stats`.
#[derive(Args, Debug, Clone)]
pub struct StatsArgs {
    /// Family of tests to run.
    #[arg(value_enum, default_value_t = Family::All)]
    pub family: Family,
    /// Larger samples (several times slower; the default suite takes under 2 minutes on 2 cores).
    #[arg(long)]
    pub thorough: bool,
    /// Output directory for stats.csv, stats.md and the plots.
    #[arg(long, default_value = "results/stats")]
    pub out: PathBuf,
    /// Worker threads (0 = all cores); results do not depend on it.
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
}

/// A verdict, or the verdict a test is expected to reach.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// The hypothesis (unbiased, right pdf, conserves energy, …) is not rejected.
    Pass,
    /// It is rejected.
    Fail,
}

impl Outcome {
    /// `pass` / `fail`.
    pub fn as_str(self) -> &'static str {
        match self {
            Outcome::Pass => "pass",
            Outcome::Fail => "fail",
        }
    }
    /// `Pass` when `ok`.
    pub fn from_bool(ok: bool) -> Self {
        if ok { Outcome::Pass } else { Outcome::Fail }
    }
}

/// One row of the report.
#[derive(Clone, Debug)]
pub struct TestRow {
    /// Test name, `family/what/variant` (no commas).
    pub test: String,
    /// The test statistic (t, χ², a slope, a maximum, …; see the family's docs).
    pub statistic: f64,
    /// p-value where the test has one.
    pub p_value: Option<f64>,
    /// `Fail` for planted controls.
    pub expected: Outcome,
    /// What the test concluded.
    pub verdict: Outcome,
}

impl TestRow {
    /// A row whose verdict is `Pass` when `ok`.
    pub fn new(test: impl Into<String>, statistic: f64, p_value: Option<f64>, expected: Outcome, ok: bool) -> Self {
        TestRow { test: test.into(), statistic, p_value, expected, verdict: Outcome::from_bool(ok) }
    }
    /// True when the verdict is the expected one.
    pub fn as_expected(&self) -> bool {
        self.verdict == self.expected
    }
}

/// Sample sizes: the default (CI) size or `--thorough`.
#[derive(Clone, Copy, Debug, Default)]
pub struct Settings {
    /// Larger samples.
    pub thorough: bool,
}

impl Settings {
    /// `default` normally, `thorough` with `--thorough`.
    pub fn pick<T>(&self, default: T, thorough: T) -> T {
        if self.thorough { thorough } else { default }
    }
}

/// What one family produced: its rows and the plots to write (file stem, plot).
#[derive(Default)]
pub struct FamilyReport {
    /// Test rows.
    pub rows: Vec<TestRow>,
    /// Plots, written by the runner as `stem.png` and `stem.svg`.
    pub plots: Vec<(String, LinePlot)>,
}

/// Runs one family (or all of them) and returns the rows and plots, writing nothing.
pub fn run_family(family: Family, s: &Settings) -> Result<FamilyReport> {
    Ok(match family {
        Family::All => {
            let mut all = FamilyReport::default();
            for f in Family::EACH {
                let r = run_family(f, s)?;
                all.rows.extend(r.rows);
                all.plots.extend(r.plots);
            }
            all
        }
        Family::Rr => rr::run(s)?,
        Family::Discrepancy => discrepancy::run(s)?,
        Family::Chi2 => chi2::run(s)?,
        Family::Brdf => brdf::run(s)?,
        Family::Convergence => convergence::run(s)?,
        Family::Progressive => progressive::run(s)?,
    })
}

/// Runs the command: prints the table, writes `stats.csv`, `stats.md` and the plots
/// into `args.out`, and returns the rows.
pub fn run(args: &StatsArgs) -> Result<Vec<TestRow>> {
    let s = Settings { thorough: args.thorough };
    let pool = crate::pipeline::thread_pool(args.threads)?;
    let t0 = Instant::now();
    let mut rows = Vec::new();
    let mut plots = Vec::new();
    let families: Vec<Family> = if args.family == Family::All { Family::EACH.to_vec() } else { vec![args.family] };
    for f in families {
        let t = Instant::now();
        let r = pool.install(|| run_family(f, &s))?;
        eprintln!("stats {}: {} tests in {:.1} s", f.name(), r.rows.len(), t.elapsed().as_secs_f64());
        rows.extend(r.rows);
        plots.extend(r.plots);
    }
    let seconds = t0.elapsed().as_secs_f64();
    std::fs::create_dir_all(&args.out).with_context(|| format!("{}: cannot create the output directory", args.out.display()))?;
    crate::film::write_atomic(&args.out.join("stats.csv"), csv(&rows).as_bytes())
        .with_context(|| format!("{}: cannot write stats.csv", args.out.display()))?;
    let md = markdown(&rows, args, seconds, pool.current_num_threads());
    crate::film::write_atomic(&args.out.join("stats.md"), md.as_bytes())
        .with_context(|| format!("{}: cannot write stats.md", args.out.display()))?;
    let mut written = Vec::new();
    for (stem, p) in &plots {
        let (png, _) = line_plot(&args.out.join(stem), p)?;
        written.push(png);
    }
    out!("{}", table(&rows));
    let bad = rows.iter().filter(|r| !r.as_expected()).count();
    outln!("{} tests, {} as expected, {} not; {:.1} s", rows.len(), rows.len() - bad, bad, seconds);
    outln!("wrote {} and {}", args.out.join("stats.csv").display(), args.out.join("stats.md").display());
    for p in written {
        outln!("wrote {} (+ .svg)", p.display());
    }
    Ok(rows)
}

/// `photonlab stats`: Ok exactly when every verdict equals its expected value.
pub fn run_cli(args: &StatsArgs) -> Result<()> {
    let rows = run(args)?;
    let bad: Vec<&str> = rows.iter().filter(|r| !r.as_expected()).map(|r| r.test.as_str()).collect();
    if !bad.is_empty() {
        bail!("{} test(s) did not reach their expected verdict: {}", bad.len(), bad.join(", "));
    }
    Ok(())
}

/// Formats a number compactly: plain for moderate magnitudes, scientific otherwise.
pub fn fmt_num(x: f64) -> String {
    if x.is_nan() {
        "nan".into()
    } else if x.is_infinite() {
        if x > 0.0 { "inf".into() } else { "-inf".into() }
    } else if x == 0.0 {
        "0".into()
    } else if (1e-3..1e6).contains(&x.abs()) {
        let digits = (5 - x.abs().log10().floor() as i32).clamp(0, 8) as usize;
        let s = format!("{x:.digits$}");
        if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.').to_string() } else { s }
    } else {
        format!("{x:.4e}")
    }
}

fn p_str(p: Option<f64>) -> String {
    p.map(fmt_num).unwrap_or_default()
}

/// The rows as CSV with the header `test,statistic,p_value,expected,verdict`
/// (the `csv` crate: fields quoted where needed, one schema for header and rows).
pub fn csv(rows: &[TestRow]) -> String {
    let mut w = ::csv::WriterBuilder::new().terminator(::csv::Terminator::Any(b'\n')).from_writer(Vec::new());
    let _ = w.write_record(["test", "statistic", "p_value", "expected", "verdict"]);
    for r in rows {
        let _ =
            w.write_record([r.test.clone(), fmt_num(r.statistic), p_str(r.p_value), r.expected.as_str().into(), r.verdict.as_str().into()]);
    }
    String::from_utf8(w.into_inner().unwrap_or_default()).unwrap_or_default()
}

fn markdown(rows: &[TestRow], args: &StatsArgs, seconds: f64, threads: usize) -> String {
    let bad = rows.iter().filter(|r| !r.as_expected()).count();
    let mut s = String::new();
    let _ = writeln!(s, "# photonlab statistical tests\n");
    let _ = writeln!(
        s,
        "`photonlab stats {}{}`: {} tests, {} with the expected verdict, {} without; {:.1} s on {} threads.\n",
        args.family.name(),
        if args.thorough { " --thorough" } else { "" },
        rows.len(),
        rows.len() - bad,
        bad,
        seconds,
        threads
    );
    let _ = writeln!(s, "| test | statistic | p_value | expected | verdict |");
    let _ = writeln!(s, "|---|---:|---:|---|---|");
    for r in rows {
        let mark = if r.as_expected() { "" } else { " **(unexpected)**" };
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {}{} |",
            r.test,
            fmt_num(r.statistic),
            p_str(r.p_value),
            r.expected.as_str(),
            r.verdict.as_str(),
            mark
        );
    }
    s.push_str(LEGEND);
    s
}

const LEGEND: &str = "
## What the statistics are

- `rr/*`: Welch's t between the estimator with the policy and without roulette (same
  maximum depth, independent seeds), α = 0.001; `*/mde%` rows give the smallest
  relative bias the sample detects with 80 % power (must be ≤ 1 %). `rr/*/broken`
  divides no survivor by its survival probability (planted, must fail).
- `discrepancy/l2/*`: Warnock's L2-star discrepancy T; `ratio` = T(random) / T(set) at
  N = 2^14 (must be ≥ 2.5); `slope` = log–log slope over N ≥ 2^8, within 0.12 of the
  theoretical rate fitted over the same N: (log N)^k / N with k = d/2 (Halton
  sequence) or (d − 1)/2 (Hammersley point set), N^−1/2 for random (RMS of 4 seeds).
  `star2d` rows: the exact 2-D star discrepancy, rates (log N)^2 / N (Halton) and
  log N / N (Hammersley). `diagonal` is a planted degenerate set (must fail).
- `chi2/*`: Pearson's χ² of a (θ, φ) histogram of 10^6 samples against expected
  counts from adaptive quadrature of the routine's own pdf, bins expecting < 5
  pooled; Šidák-corrected level over the family (family-wise α = 0.01). Glass and
  mirror rows test the discrete reflect / refract choice against the Fresnel
  probability. `planted` rows test correct samples against a wrong pdf (must fail).
- `brdf/albedo/*`: largest directional albedo over incident angles 0–89° (numerical
  integration; must be ≤ 1.001); `brdf/reciprocity/*`: largest relative
  |f(wi,wo) − f(wo,wi)| (must be ≤ 10^−3); `brdf/energy/*`: flux scattered by the
  delta BSDFs (≤ 1).
- `convergence/*`: log–log slope of the MSE against samples per pixel (random: −1 ±
  0.15; Halton / Hammersley: at least 0.2 steeper) or photons (≤ −0.3).
- `progressive/*`: log–log slope of the MSE against passes of `sppm` and `ppm`
  (exact reference), within 0.15 of Knaus & Zwicker's −min(α, 2(1 − α)); the
  `planted` rows keep the radius fixed (α = 1) and are held to −2/3 (must fail).
";

/// The rows as an aligned text table.
pub fn table(rows: &[TestRow]) -> String {
    let w = rows.iter().map(|r| r.test.len()).max().unwrap_or(4).max(4);
    let mut s = format!("{:<w$}  {:>12}  {:>11}  {:<8}  {}\n", "test", "statistic", "p_value", "expected", "verdict");
    for r in rows {
        let flag = if r.as_expected() { "" } else { "   <-- unexpected" };
        let _ = writeln!(
            s,
            "{:<w$}  {:>12}  {:>11}  {:<8}  {}{}",
            r.test,
            fmt_num(r.statistic),
            p_str(r.p_value),
            r.expected.as_str(),
            r.verdict.as_str(),
            flag
        );
    }
    s
}

/// Sample mean and unbiased variance (sequential sums: deterministic).
pub fn mean_var(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    if x.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    let m = x.iter().sum::<f64>() / n;
    let v = if x.len() > 1 { x.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / (n - 1.0) } else { 0.0 };
    (m, v)
}

/// Result of Welch's unequal-variance t-test.
#[derive(Clone, Copy, Debug)]
pub struct Welch {
    /// t statistic of mean(a) − mean(b).
    pub t: f64,
    /// Welch–Satterthwaite degrees of freedom.
    pub df: f64,
    /// Two-sided p-value.
    pub p: f64,
    /// Standard error of the difference of means.
    pub se: f64,
    /// Mean of the first sample.
    pub mean_a: f64,
    /// Mean of the second sample.
    pub mean_b: f64,
}

/// Welch's two-sample t-test (two-sided).
pub fn welch(a: &[f64], b: &[f64]) -> Welch {
    let (ma, va) = mean_var(a);
    let (mb, vb) = mean_var(b);
    let (na, nb) = (a.len() as f64, b.len() as f64);
    let (sa, sb) = (va / na, vb / nb);
    let se = (sa + sb).sqrt();
    let df = (sa + sb).powi(2) / (sa * sa / (na - 1.0) + sb * sb / (nb - 1.0));
    let t = if se > 0.0 {
        (ma - mb) / se
    } else if ma == mb {
        0.0
    } else {
        f64::INFINITY
    };
    let p = match StudentsT::new(0.0, 1.0, df.max(1.0)) {
        Ok(d) if t.is_finite() => (2.0 * (1.0 - d.cdf(t.abs()))).clamp(0.0, 1.0),
        _ if t == 0.0 => 1.0,
        _ => 0.0,
    };
    Welch { t, df, p, se, mean_a: ma, mean_b: mb }
}

/// Quantile of the standard normal distribution.
pub fn normal_quantile(p: f64) -> f64 {
    Normal::new(0.0, 1.0).map(|n| n.inverse_cdf(p)).unwrap_or(f64::NAN)
}

/// Per-test level that keeps the family-wise level `alpha` over `m` independent
/// tests (Šidák): 1 − (1 − α)^(1/m).
pub fn sidak(alpha: f64, m: usize) -> f64 {
    1.0 - (1.0 - alpha).powf(1.0 / m.max(1) as f64)
}

/// Descriptions of the rows whose verdict differs from the expected one.
pub fn unexpected(rows: &[TestRow]) -> Vec<String> {
    rows.iter()
        .filter(|r| !r.as_expected())
        .map(|r| {
            format!(
                "{}: statistic {} p {} expected {} got {}",
                r.test,
                fmt_num(r.statistic),
                p_str(r.p_value),
                r.expected.as_str(),
                r.verdict.as_str()
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn welch_detects_shift_and_accepts_equal_means() {
        // Deterministic, symmetric samples: equal means give t = 0.
        let a: Vec<f64> = (0..1000).map(|i| (i % 10) as f64).collect();
        let b: Vec<f64> = (0..500).map(|i| (i % 10) as f64 * 1.0).collect();
        let w = welch(&a, &b);
        assert!(w.t.abs() < 1e-9 && w.p > 0.99, "{w:?}");
        let c: Vec<f64> = b.iter().map(|v| v + 1.0).collect();
        let w = welch(&a, &c);
        assert!(w.t < -5.0 && w.p < 1e-8, "{w:?}");
        // Standard error from the population variance 8.25 of 0..9.
        assert!((w.se - ((8.25f64 * 1000.0 / 999.0) / 1000.0 + (8.25 * 500.0 / 499.0) / 500.0).sqrt()).abs() < 1e-12);
    }

    #[test]
    fn sidak_and_quantiles() {
        assert!((sidak(0.05, 1) - 0.05).abs() < 1e-12);
        assert!(sidak(0.01, 20) < 0.01 / 19.0 && sidak(0.01, 20) > 0.01 / 21.0);
        assert!((normal_quantile(0.975) - 1.959964).abs() < 1e-5);
    }

    #[test]
    fn formats_and_csv() {
        assert_eq!(fmt_num(0.0), "0");
        assert_eq!(fmt_num(1.5), "1.5");
        assert_eq!(fmt_num(1e-7), "1.0000e-7");
        let rows = vec![TestRow::new("a/b", 2.0, None, Outcome::Fail, false), TestRow::new("c", 1.0, Some(0.5), Outcome::Pass, false)];
        let c = csv(&rows);
        assert!(c.starts_with("test,statistic,p_value,expected,verdict\na/b,2,,fail,fail\nc,1,0.5,pass,fail\n"), "{c}");
        let quoted = csv(&[TestRow::new("x,y", 1.0, None, Outcome::Pass, true)]);
        assert!(quoted.ends_with("\"x,y\",1,,pass,pass\n"), "{quoted}");
        assert_eq!(unexpected(&rows).len(), 1);
    }
}
