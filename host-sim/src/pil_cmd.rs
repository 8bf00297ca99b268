//! `eval --pil`: the rows of `eval`, run by the board's controller on a target over the
//! link, each period compared with the same target code run here, and the target's time
//! per period.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Result, bail};
use clap::Args;
use firmware::link::Format;
use host_common::provenance::Provenance;
use host_sim::eval::{ControllerKind, Row};
use host_sim::pil::link::Session;
use host_sim::pil::{Board, Check, ICOUNT, NS_PER_INSTRUCTION, Place, handshake, run_row};
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;
use twin::Scenario;

use crate::EvalArgs;
use crate::subject::{Monitor, Subject};

/// Longest wait for one answer `--pil-timeout` may set, s.
const MAX_TIMEOUT_S: f64 = 3600.0;

/// Where the controller runs, when not here.
#[derive(Args)]
pub struct PilArgs {
    /// Run the policy rows on a target over the link instead of here: `qemu:TARGET` starts
    /// the `pil` application for one of the matrix's targets in QEMU (processor in the
    /// loop); `serial:PATH` talks to a board on a serial port (hardware in the loop);
    /// `exec:PATH` starts a program that speaks the link on its standard input and output.
    /// Each period is compared with the same controller code run here; exits 1 on any
    /// difference.
    #[arg(long, value_name = "SPEC")]
    pub pil: Option<std::ffi::OsString>,
    /// The `pil` application's ELF for `--pil qemu:TARGET` [default: cargo's release build
    /// of it for TARGET].
    #[arg(long, value_name = "PATH", requires = "pil")]
    pub pil_elf: Option<PathBuf>,
    /// The shipped policy the target holds, and the reference here with it: `shipped` (two
    /// levels, so no refined controller; the `pil` application) or `desk` (the nine-level
    /// desk policy on the desk rig, whose scenarios need `--rig rigs/desk-identified.toml`;
    /// the `pil-desk` application; no envelope, so no monitored controller).
    #[arg(long, value_enum, default_value_t = Board::Shipped, requires = "pil")]
    pub pil_policy: Board,
    /// Seconds to wait for each answer of the target before giving up (exit 2).
    #[arg(long, default_value_t = 10.0, requires = "pil")]
    pub pil_timeout: f64,
}

impl PilArgs {
    /// Where the controller runs, checked with the rest of `eval`'s input before any work:
    /// the target runs the policy compiled into it with its envelope, so no `--policy` or
    /// `--envelope` of `subject`'s, and only its rows.
    pub fn place(
        &self,
        subject: &Subject,
        monitor: &Monitor,
        controllers: &[ControllerKind],
    ) -> Result<Option<Place>> {
        let Some(spec) = &self.pil else {
            return Ok(None);
        };
        if subject.policy.is_some() {
            bail!(
                "--pil runs the policy compiled into the target's application, found --policy \
                 (choose a shipped one with --pil-policy, or export yours into shipped/src and \
                 rebuild the pil application)"
            );
        }
        if monitor.envelope.is_some() {
            bail!(
                "--pil runs the runtime monitor with the envelope compiled into the target's \
                 application, found --envelope (leave it out)"
            );
        }
        if let Some(c) = controllers.iter().find(|c| !c.runs_policy()) {
            let runs: Vec<_> = ControllerKind::on_target().map(|k| k.to_string()).collect();
            bail!(
                "--pil runs the controllers {}, found --controller {c}",
                runs.join(", ")
            );
        }
        let board = self.pil_policy;
        if let Some(why) = host_sim::eval::unrefinable(controllers, board.refines()) {
            bail!("--pil-policy {board}: {why}");
        }
        if let Some(c) = controllers
            .iter()
            .find(|c| c.monitored() && !board.monitors())
        {
            bail!(
                "--pil-policy {board}: no envelope is measured for it, so the target refuses \
                 its runtime monitor; found --controller {c} (run policy or policy-int)"
            );
        }
        if !(self.pil_timeout > 0.0
            && self.pil_timeout <= MAX_TIMEOUT_S
            && weights::plain(self.pil_timeout))
        {
            bail!(
                "--pil-timeout must lie in (0, {MAX_TIMEOUT_S}] s, a normal number, found {:?}",
                self.pil_timeout
            );
        }
        Place::parse(spec, self.pil_elf.as_deref(), board).map(Some)
    }
}

/// One row's comparison and timing, beside the row.
#[derive(Serialize)]
struct PilRow<'a> {
    target: &'a str,
    controller: String,
    scenario: &'a str,
    horizon: u32,
    #[serde(flatten)]
    check: Check,
}

/// Runs `jobs` (horizon, scenario, controller) on the target at `place`.
pub fn run(a: &EvalArgs, place: &Place, jobs: &[(u32, &Scenario, ControllerKind)]) -> Result<bool> {
    let timeout = Duration::from_secs_f64(a.pil.pil_timeout);
    let mut target = Session::new(place.start(timeout)?);
    let board = a.pil.pil_policy;
    let mut reference = Session::new(board.reference());
    let scenarios: Vec<Scenario> = jobs.iter().map(|j| j.1.clone()).collect();
    let total = jobs.len() as u64 * a.episodes;
    let bar = ProgressBar::new(total).with_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} episodes, {elapsed}, ETA {eta} {msg}")
            .expect("static template"),
    );
    let (mut rows, mut checks) = (Vec::new(), Vec::new());
    for &(h, s, c) in jobs {
        let format = if c.int() { Format::Int8 } else { Format::F32 };
        let info = handshake(&mut target, &mut reference, format, &scenarios, board)?;
        bar.set_message(format!("{c} on {} at {h}", s.name));
        let (eps, check) = run_row(
            &mut target,
            &mut reference,
            (&info, c),
            s,
            h,
            a.seed,
            a.episodes,
            || bar.inc(1),
        )?;
        rows.push(Row::from_episodes(
            &c.to_string(),
            &s.name,
            (h, s.params.tau),
            a.seed,
            &eps,
        ));
        checks.push(PilRow {
            target: "",
            controller: c.to_string(),
            scenario: &s.name,
            horizon: h,
            check,
        });
    }
    bar.finish_and_clear();
    let name = place.name();
    checks.iter_mut().for_each(|c| c.target = &name);
    print(a, &rows, &checks)?;
    let equal = checks.iter().all(|c| c.check.mismatches == 0);
    if !equal {
        host_common::errln!("the target's answers differ from the reference's (see the table)");
    }
    Ok(crate::met_min_success(a, &rows) && equal)
}

fn print(a: &EvalArgs, rows: &[Row], checks: &[PilRow<'_>]) -> Result<()> {
    if a.json {
        let doc = serde_json::json!({
            "seed": a.seed,
            "rows": rows,
            "pil": checks,
            "provenance": Provenance::of_this_run("host-sim"),
        });
        host_common::outln!("{}", serde_json::to_string_pretty(&doc)?);
        return Ok(());
    }
    host_common::out!("{}", host_sim::eval::format_table(rows));
    host_common::out!("{}", host_sim::eval::format_failures(rows, a.seed));
    host_common::outln!(
        "\n{:<40} {:<18} {:<11} {:>10} {:>10} {:>12} {:>12} {:>12} {:>9}",
        "target",
        "scenario",
        "ctrl",
        "periods",
        "mismatch",
        "median us",
        "p99 us",
        "worst us",
        "overruns"
    );
    for c in checks {
        let us = |ns: u64| ns as f64 / 1e3;
        let [median, p99, worst] = c.check.time_ns;
        host_common::outln!(
            "{:<40} {:<18} {:<11} {:>10} {:>10} {:>12.1} {:>12.1} {:>12.1} {:>9}",
            c.target,
            c.scenario,
            c.controller,
            c.check.periods,
            c.check.mismatches,
            us(median),
            us(p99),
            us(worst),
            c.check.overruns
        );
        if let Some(m) = &c.check.first {
            host_common::outln!(
                "  first mismatch: episode {} period {}: target {}, reference {}",
                m.episode,
                m.period,
                m.target,
                m.reference
            );
        }
    }
    host_common::outln!(
        "\nIn QEMU the time is virtual: {NS_PER_INSTRUCTION} ns per instruction (-icount \
         {ICOUNT}), so it counts the instructions of the period."
    );
    Ok(())
}
