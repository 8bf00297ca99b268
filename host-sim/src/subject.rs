//! Which policy runs, on which machine: the flags `eval`, `agree`, `render`, `soak`,
//! `envelope` and `startup` share; and the envelope of the commands that run a monitored
//! controller (`eval`, `render`, `soak`).

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use host_sim::eval::{ControllerKind, Net, names};
use twin::Machine;
use weights::levels::GivenLevels;

/// Which policy runs, on which machine.
#[derive(Args)]
pub struct Subject {
    /// A policy instead of the shipped one (the `shipped` crate): a run directory, or a
    /// checkpoint as PyTorch users save it (safetensors, torch.save zip, Stable-Baselines3
    /// model.zip, ONNX; fc1/fc2/fc3, nn.Sequential indices, prefixed layouts), of any
    /// supported width.
    #[arg(long)]
    pub policy: Option<PathBuf>,
    /// Tensor-name prefix of the network in --policy, when it holds several.
    #[arg(long, requires = "policy")]
    pub prefix: Option<String>,
    /// The duty level each output of --policy drives, for a checkpoint that records none
    /// (PyTorch, Stable-Baselines3, ONNX): comma-separated fractions of the full push in
    /// increasing order, one per output (`-1,-0.2,0,0.2,1`). A two-output checkpoint
    /// without them drives the paper's two; a file that records other levels refuses them.
    #[arg(long, requires = "policy", allow_hyphen_values = true)]
    pub levels: Option<String>,
    /// The machine the scenarios are built on (a rig file, `rigs/`): its physics, encoders,
    /// dead time, track and continuous-time world. Without it, the rig the policy file
    /// records, or Gymnasium's machine; a different one than the recorded is warned about.
    #[arg(long)]
    pub rig: Option<PathBuf>,
}

/// The envelope a monitored controller keeps, where one may run.
#[derive(Args, Default)]
pub struct Monitor {
    /// The runtime monitor's envelope for --controller monitored: the JSON `host-sim
    /// envelope --json` prints (for --policy, measured with the same --policy). The shipped
    /// policy's is compiled in.
    #[arg(long)]
    pub envelope: Option<PathBuf>,
}

impl Monitor {
    /// The file read, by flag.
    pub fn inputs(&self) -> impl Iterator<Item = (&'static str, PathBuf)> {
        self.envelope.clone().map(|p| ("--envelope", p)).into_iter()
    }
}

impl Subject {
    /// The files this subject reads, by flag: the policy's (a run directory's
    /// `policy.safetensors`) and the rig file.
    pub fn inputs(&self) -> Vec<(&'static str, PathBuf)> {
        let policy = self.policy.as_deref().map(weights::checkpoint::policy_file);
        [("--policy", policy), ("--rig", self.rig.clone())]
            .into_iter()
            .filter_map(|(flag, p)| Some((flag, p?)))
            .collect()
    }

    /// The levels of --levels, checked.
    pub fn given(&self) -> Result<Option<GivenLevels>> {
        let parse = |l: &str| GivenLevels::parse(l, "--levels");
        Ok(self.levels.as_deref().map(parse).transpose()?)
    }

    /// [`Subject::load`] for `kinds` of controller: the network with its integer version if
    /// one runs it, and the envelope of `monitor`. Refused: the monitored controller for a
    /// --policy without an --envelope measured for it.
    pub fn load_for(&self, kinds: &[ControllerKind], monitor: &Monitor) -> Result<(Machine, Net)> {
        let monitored = kinds.iter().find(|k| k.monitored());
        if let (Some(_), None) = (&monitor.envelope, monitored) {
            anyhow::bail!(
                "--envelope is read by --controller monitored or monitored-int alone; expected \
                 one of them, found {}",
                names(kinds)
            );
        }
        if let (Some(path), None, Some(k)) = (&self.policy, &monitor.envelope, monitored) {
            anyhow::bail!(
                "--controller {k} needs the envelope measured for --policy {}: give \
                 --envelope FILE, the JSON `host-sim envelope --policy ... --json` prints",
                weights::shown(path)
            );
        }
        let int = kinds.iter().any(|k| k.int());
        let policy = kinds.iter().any(|k| k.needs_policy());
        if !policy {
            self.refuse_unread(kinds, None)?;
        }
        let (machine, net) = self.load(int, policy)?;
        if !policy {
            self.refuse_unread(kinds, Some(&machine))?;
        }
        if let Some(why) = host_sim::eval::idle_between(kinds, net.levels()) {
            let whose = (self.policy.as_deref()).map_or("the shipped policy".into(), |p| {
                format!("--policy {}", weights::shown(p))
            });
            anyhow::bail!("{whose}: {why}");
        }
        let net = match monitor.envelope.as_deref() {
            Some(path) => {
                let (envelope, rig) = host_sim::envelope::read_for(path, Some(net.digest()))?;
                net.with_envelope(envelope, rig)
            }
            None => net,
        };
        if monitored.is_some() {
            net.check_envelope_on(&machine.rig)
                .map_err(|why| anyhow::anyhow!("--controller {}: {why}", names(kinds)))?;
        }
        Ok((machine, net))
    }

    /// Refuses --policy, and --levels, where `kinds` (none of which runs the network or
    /// rounds to its levels) leave them changing nothing: the file is then read for the rig
    /// it records alone, which --rig replaces, or which is Gymnasium's, the machine without
    /// it. `gives` is the machine the file gave, once read.
    fn refuse_unread(&self, kinds: &[ControllerKind], gives: Option<&Machine>) -> Result<()> {
        let Some(path) = &self.policy else {
            return Ok(());
        };
        let read_by = ControllerKind::read_by();
        let (policy, found) = (weights::shown(path), names(kinds));
        if self.levels.is_some() {
            anyhow::bail!("--levels {read_by}; expected one of them, found {found}");
        }
        match (&self.rig, gives) {
            (Some(rig), _) => anyhow::bail!(
                "--policy {policy} {read_by}, and for the rig it records where no --rig gives \
                 the machine; expected one of them, or --policy left out, found {found} and \
                 --rig {}",
                weights::shown(rig)
            ),
            (None, Some(m)) if *m == Machine::GYMNASIUM => anyhow::bail!(
                "--policy {policy} {read_by}, and for the rig it records, which is Gymnasium's \
                 machine (or none), the machine without it; expected one of them, or --policy \
                 left out, found {found}"
            ),
            _ => Ok(()),
        }
    }

    /// The machine, and the network (with its integer version if `int`), loaded lazily by
    /// the commands after their cheaper checks. Where nothing needs the policy (`policy`
    /// false: baselines that take none of its levels), --rig is the machine and a policy's
    /// own rig is no concern of it.
    pub fn load(&self, int: bool, policy: bool) -> Result<(Machine, Net)> {
        let given = self.rig.as_deref().map(twin::rigfile::load).transpose()?;
        if let (Some(machine), false) = (given, policy) {
            return Ok((machine, Net::shipped()));
        }
        let Some(path) = &self.policy else {
            return Ok((
                twin::rigfile::choose_warned(given, Some(Machine::GYMNASIUM)),
                Net::shipped(),
            ));
        };
        let import =
            weights::checkpoint::load_with(path, self.prefix.as_deref(), self.given()?.as_ref())?;
        let source = format!("policy {}", weights::shown(path));
        let recorded = twin::rigfile::recorded(&import.metadata, &source)?;
        let machine = twin::rigfile::choose_warned(given, recorded);
        let net = Net::from_weights(&import.weights, int.then_some(&machine))
            .with_context(|| format!("policy {}", weights::shown(path)))?;
        Ok((machine, net))
    }
}
