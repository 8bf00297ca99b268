//! The training flags: one per configuration key, laid over the preset and the TOML file.
//! (A module of the `policy-export` binary, not of the library.)

use clap::Args;
use policy_export::config::{Algo, Config, Init, KernelChoice, TargetUpdate, Unit};
use policy_export::nn::Loss;

/// One flag per configuration key; see `Config` for their meaning.
#[derive(Args)]
pub struct Overrides {
    #[arg(long, value_enum)]
    algo: Option<Algo>,
    #[arg(long)]
    width: Option<usize>,
    #[arg(long)]
    lr: Option<f64>,
    #[arg(long)]
    adam_beta1: Option<f64>,
    #[arg(long)]
    adam_beta2: Option<f64>,
    #[arg(long)]
    adam_eps: Option<f64>,
    #[arg(long)]
    gamma: Option<f64>,
    #[arg(long)]
    buffer_size: Option<usize>,
    #[arg(long)]
    batch_size: Option<usize>,
    #[arg(long)]
    learning_starts: Option<usize>,
    #[arg(long)]
    train_every: Option<usize>,
    #[arg(long, value_enum)]
    train_unit: Option<Unit>,
    #[arg(long)]
    updates_per_train: Option<usize>,
    #[arg(long)]
    max_env_steps: Option<u64>,
    #[arg(long, value_enum)]
    target_update: Option<TargetUpdate>,
    #[arg(long)]
    target_period: Option<usize>,
    #[arg(long, value_enum)]
    target_period_unit: Option<Unit>,
    #[arg(long)]
    tau: Option<f64>,
    #[arg(long)]
    eps_start: Option<f64>,
    #[arg(long)]
    eps_end: Option<f64>,
    #[arg(long)]
    eps_decay: Option<f64>,
    #[arg(long, value_enum)]
    eps_unit: Option<Unit>,
    #[arg(long)]
    episodes: Option<usize>,
    #[arg(long)]
    max_steps: Option<u32>,
    #[arg(long)]
    grad_clip: Option<f64>,
    #[arg(long, value_enum)]
    loss: Option<Loss>,
    #[arg(long, value_enum)]
    init: Option<Init>,
    #[arg(long)]
    eval_every: Option<usize>,
    #[arg(long)]
    eval_episodes: Option<usize>,
    #[arg(long)]
    eval_max_steps: Option<u32>,
    #[arg(long)]
    stop_when_perfect: Option<bool>,
    #[arg(long)]
    final_eval_episodes: Option<usize>,
    #[arg(long)]
    finalists: Option<usize>,
    #[arg(long)]
    finalist_episodes: Option<usize>,
    #[arg(long)]
    finalist_max_steps: Option<u32>,
    #[arg(long, value_enum)]
    kernel: Option<KernelChoice>,
    #[arg(long)]
    compensate: Option<bool>,
    #[arg(long)]
    domain: Option<String>,
    #[arg(long)]
    eval_domain: Option<String>,
    #[arg(long)]
    finalist_domain: Option<String>,
    #[arg(long)]
    reward: Option<String>,
}

impl Overrides {
    pub fn apply(&self, c: &mut Config) {
        macro_rules! set {
            ($($f:ident),*) => { $( if let Some(v) = self.$f { c.$f = v; } )* };
        }
        set!(
            algo,
            width,
            lr,
            adam_beta1,
            adam_beta2,
            adam_eps,
            gamma,
            buffer_size,
            batch_size,
            learning_starts,
            train_every,
            train_unit,
            updates_per_train,
            max_env_steps,
            target_update,
            target_period,
            target_period_unit,
            tau,
            eps_start,
            eps_end,
            eps_decay,
            eps_unit,
            episodes,
            max_steps,
            grad_clip,
            loss,
            init,
            eval_every,
            eval_episodes,
            eval_max_steps,
            stop_when_perfect,
            final_eval_episodes,
            finalists,
            finalist_episodes,
            finalist_max_steps,
            kernel,
            compensate
        );
        for (field, v) in [
            (&mut c.domain, &self.domain),
            (&mut c.eval_domain, &self.eval_domain),
            (&mut c.finalist_domain, &self.finalist_domain),
            (&mut c.reward, &self.reward),
        ] {
            if let Some(v) = v {
                field.clone_from(v);
            }
        }
    }
}
