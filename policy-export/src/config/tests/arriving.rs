//! Values as they arrive, after any TOML escape the check of a file's text cannot see
//! through, and values that leave a mode read by nothing.

use super::super::Config;

/// The configuration `f` makes of the paper's is refused with `want` among its words.
fn refused(f: fn(&mut Config), want: &str) {
    let mut c = Config::paper();
    f(&mut c);
    let e = c.validate().unwrap_err().to_string();
    assert!(e.contains(want), "{e:?} lacks {want:?}");
}

#[test]
fn a_spec_that_reads_as_zero_is_refused_as_it_arrives() {
    // `1e\u002d400` in a file hid these from the check of its text.
    refused(
        |c| c.levels = "-1,1e-400,1".into(),
        "levels: line 1, column 4: 1e-400",
    );
    refused(
        |c| c.domain = "noise=1e-400".into(),
        "domain: line 1, column 7: 1e-400",
    );
    refused(
        |c| c.reward = "env+effort=1e-400".into(),
        "reward: line 1, column 12: 1e-400",
    );
}

#[test]
fn a_decay_that_never_moves_epsilon_or_is_over_at_once_is_refused_and_one_that_does_is_taken() {
    // Epsilon stayed at eps_start for the whole run: eps_end was read by nothing.
    refused(
        |c| c.eps_decay = 1e300,
        "eps_decay (1e300) leaves epsilon at eps_start for the whole run (60000 steps at most)",
    );
    // The decay factor moves below 1, but epsilon, a hundredth above its end, does not.
    refused(
        |c| (c.eps_end, c.eps_decay) = (c.eps_start - 0.01, 3e19),
        "eps_decay (3e19) leaves epsilon at eps_start",
    );
    refused(
        |c| (c.eps_unit, c.eps_decay) = (super::super::Unit::Episodes, 1e300),
        "for the whole run (300 episodes at most)",
    );
    // A step budget ends the run sooner: 1e19 moves epsilon in 60,000 steps, not in 100.
    refused(
        |c| (c.max_env_steps, c.eps_decay) = (100, 1e19),
        "for the whole run (100 steps at most)",
    );
    // The mirror: at eps_end from the second step on, eps_start read once.
    refused(
        |c| c.eps_decay = 1e-300,
        "eps_decay (1e-300) takes epsilon to eps_end within one step, so eps_start is read once",
    );
    refused(
        |c| (c.eps_unit, c.eps_decay) = (super::super::Unit::Episodes, 0.02),
        "within one episode",
    );
    // A decay its own limit refuses is refused once, by that limit.
    let mut c = Config::paper();
    c.eps_decay = 0.0;
    let e = c.validate().unwrap_err().to_string();
    assert!(
        e.contains("eps_decay must be > 0") && !e.contains("takes epsilon"),
        "{e}"
    );
    let mut c = Config::paper();
    c.eps_decay = 0.05;
    c.validate().unwrap();
    c.eps_decay = 1e19;
    c.validate().unwrap();
    // exp(-60000 / 1e15) is below 1 in f64, and epsilon moves with it.
    c.eps_decay = 1e15;
    c.validate().unwrap();
}

/// With no discount the loss never looks past the next reward: the target network, and
/// every key that chooses, copies or averages it, changes nothing (the weights came out the
/// same for each).
#[test]
fn without_a_discount_the_target_networks_keys_are_unread() {
    let zero = |toml: &str| {
        let mut c = Config::paper().overlay_toml(toml, "t.toml").unwrap();
        c.unread(&Config::paper()).map_err(|e| e.0)
    };
    let e = zero("gamma = 0\nalgo = \"dqn\"\n").unwrap_err();
    assert_eq!(
        e,
        "algo = \"dqn\" is read only when gamma is above 0; gamma = 0.0 ignores it"
    );
    let e = zero("gamma = -0.0\ntarget_update = \"soft\"\ntau = 0.5\n").unwrap_err();
    assert!(
        e.contains("target_update = \"soft\" is read only when gamma"),
        "{e}"
    );
    assert!(e.contains("tau = 0.5 is read only when gamma"), "{e}");
    // Their defaults ask for nothing; a discount reads them all.
    assert_eq!(zero("gamma = 0\n"), Ok(()));
    assert_eq!(zero("gamma = 0.5\nalgo = \"dqn\"\n"), Ok(()));
}

/// A whole-number key given as no whole number, or past its type, is refused by its limit
/// (the range named), not by the conversion to its Rust type ("expected usize"); a key
/// without a limit by the conversion, on one line, the key first.
#[test]
fn a_count_that_is_no_whole_number_is_refused_by_its_limit() {
    let refusal = |toml: &str| Config::paper().overlay_toml(toml, "t.toml").unwrap_err().0;
    for (toml, want) in [
        (
            "episodes = 1.5",
            "t.toml: episodes must be a whole number in [1, 1000000], got 1.5",
        ),
        (
            "buffer_size = -5",
            "buffer_size must be a whole number in [1, 5000000], got -5",
        ),
        (
            "max_steps = 4294967296",
            "max_steps must be in [1, 1000000], got 4294967296",
        ),
        (
            "width = \"64\"",
            "width must be a whole number one of [16, 64, 128], got \"64\"",
        ),
        (
            "learning_starts = 1.5",
            "t.toml: learning_starts: invalid type: floating point",
        ),
    ] {
        let e = refusal(toml);
        assert!(e.contains(want) && !e.contains('\\'), "{toml}: {e}");
    }
}
