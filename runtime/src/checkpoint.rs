//! Bounded memory and checkpoints: how long a run may be without any process growing, and how a restarted
//! process gets back into a run that is older than what is kept.
//!
//! - emitter-sim keeps the truth and measurement of the last [`HISTORY_STEPS`] steps for replays; the
//!   estimator keeps the states the planner's commands echoed for as many steps (it keeps no answers: a
//!   step seen again is estimated again from the state before it). The planner keeps nothing across
//!   steps (it plans from what each estimate carries). Nothing else grows with the run (the monitor
//!   writes each step to its log as it completes and keeps no per-step record in memory when it has a
//!   log).
//! - Every [`CHECKPOINT_EVERY`] steps (at the *checkpoint steps* c = 256, 512, …) the estimator writes its
//!   state before step c to its `--checkpoint` file before it publishes that step's estimate, keeping the
//!   last [`PROCESS_CHECKPOINTS`]; emitter-sim writes the world before step c once the command of step c
//!   has come back (so the estimator has checkpointed c by then), keeping the last [`EMITTER_SNAPSHOTS`].
//! - A restarted estimator resumes from its newest checkpoint and asks emitter-sim for a replay from the
//!   step after it instead of step 0; a restarted planner asks for the step in flight only; a restarted
//!   monitor asks from the checkpoint step at or below the first step it lacks. A restarted emitter-sim
//!   flies on from its *older* snapshot b (from step 0 while it has fewer than two), re-publishing steps
//!   it had published before.
//! - When a step arrives that the estimator is past (a replay, or the world rewound by a restarted
//!   emitter-sim), it estimates it again from the state before it — echoed by a command it saw or, after
//!   its own restart, held by one of its checkpoints — so its estimates stay exactly those of the run.
//!
//! - A lock-step emitter-sim does not publish step k while the monitor's progress (the first step it lacks,
//!   [`protocol::ControlKind::Progress`]) is k − [`MONITOR_WINDOW`] or less: a monitor restarted many times
//!   cannot fall further behind (the window is below [`CHECKPOINT_EVERY`], so the first step it lacks is
//!   always newer than the older snapshot a restarted emitter-sim flies on from).
//!
//! With these orders every request lies within emitter-sim's history and the state before every step
//! seen again within the echoed states or the checkpoints kept, for any single crash and for two processes crashing at once. A request that is not (a
//! process restarted without its checkpoint in a run longer than the history, or a monitor left more than
//! [`CHECKPOINT_EVERY`] steps behind with `--monitor-window 0` or in real-time mode) is refused with an
//! error naming the steps.
//!
//! Files are JSON, written to `FILE.tmp` and renamed over `FILE` (a reader never sees half a file), and
//! carry the role and domain they belong to; a checkpoint of another role or domain is an error. They
//! survive a crash of the process (SIGKILL), not of the machine (no fsync).

use std::path::Path;

use serde::{Deserialize, Serialize, de::DeserializeOwned};

/// Steps emitter-sim keeps for replays, and the estimator keeps echoed states for.
pub const HISTORY_STEPS: u64 = 4096;

/// Steps between two checkpoints.
pub const CHECKPOINT_EVERY: u64 = 256;

/// World snapshots emitter-sim keeps in its checkpoint (it restarts from the oldest).
pub const EMITTER_SNAPSHOTS: usize = 2;

/// Checkpoints the estimator keeps in its file (each a state it can estimate the step after from).
pub const PROCESS_CHECKPOINTS: usize = 3;

/// How many steps a lock-step emitter-sim may run ahead of the monitor's progress (the default of its
/// `--monitor-window`).
pub const MONITOR_WINDOW: u64 = 128;

// A monitor within the window lacks no step older than a restarted emitter-sim's older snapshot.
const _: () = assert!(MONITOR_WINDOW < CHECKPOINT_EVERY);

// Every rewind point and every replay request lie within the history.
const _: () = assert!((PROCESS_CHECKPOINTS as u64 + 2) * CHECKPOINT_EVERY < HISTORY_STEPS);

/// Whether `step` is a checkpoint step (256, 512, …; step 0 needs none: it starts a run).
pub fn is_checkpoint_step(step: u64) -> bool {
    step > 0 && step.is_multiple_of(CHECKPOINT_EVERY)
}

/// The newest checkpoint step at or below `step` (0 if none).
pub fn checkpoint_step_at_or_below(step: u64) -> u64 {
    step - step % CHECKPOINT_EVERY
}

/// Adds `item` to the kept `list` (oldest first), keeping at most `keep`.
pub fn push_kept<T>(list: &mut Vec<T>, item: T, keep: usize) {
    list.push(item);
    if list.len() > keep {
        list.drain(..list.len() - keep);
    }
}

#[derive(Serialize, Deserialize)]
struct Envelope<T> {
    role: String,
    domain: String,
    state: T,
}

/// Writes `state` of `role` in `domain` to `path` (atomically: a temporary file renamed over it).
pub fn save<T: Serialize>(path: &Path, role: &str, domain: &str, state: &T) -> Result<(), String> {
    let envelope = Envelope { role: role.to_string(), domain: domain.to_string(), state };
    let text = serde_json::to_string(&envelope).map_err(|e| format!("checkpoint {}: {e}", path.display()))?;
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    std::fs::write(&tmp, text)
        .and_then(|()| std::fs::rename(&tmp, path))
        .map_err(|e| format!("checkpoint {}: {e}", path.display()))
}

/// Reads the checkpoint of `role` in `domain` from `path`: `None` if there is none; an error if the file
/// cannot be read or parsed or belongs to another role or domain.
pub fn load<T: DeserializeOwned>(path: &Path, role: &str, domain: &str) -> Result<Option<T>, String> {
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(format!("checkpoint {}: {e}", path.display())),
    };
    let envelope: Envelope<T> =
        serde_json::from_str(&text).map_err(|e| format!("checkpoint {}: not a checkpoint: {e}", path.display()))?;
    if envelope.role != role || envelope.domain != domain {
        return Err(format!(
            "checkpoint {}: written by the {} of domain {}, not by the {role} of domain {domain}",
            path.display(),
            envelope.role,
            envelope.domain
        ));
    }
    Ok(Some(envelope.state))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, PartialEq, Serialize, Deserialize)]
    struct State {
        step: u64,
        x: Option<[f64; 2]>,
    }

    #[test]
    fn a_saved_state_loads_back_bit_for_bit_and_only_for_its_role_and_domain() {
        let dir = std::env::temp_dir().join(format!("uavloc-ckpt-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("estimator.ckpt");
        assert_eq!(load::<State>(&path, "estimator", "d").unwrap(), None, "no file: no checkpoint");
        let s = State { step: 512, x: Some([0.1 + 0.2, -1e-300]) };
        save(&path, "estimator", "d", &s).unwrap();
        assert_eq!(load::<State>(&path, "estimator", "d").unwrap(), Some(s));
        assert!(!dir.join("estimator.ckpt.tmp").exists());
        let other = load::<State>(&path, "planner", "d").unwrap_err();
        assert!(other.contains("not by the planner"), "{other}");
        assert!(load::<State>(&path, "estimator", "e").is_err());
        std::fs::write(&path, "{\"role\": 3").unwrap();
        assert!(load::<State>(&path, "estimator", "d").unwrap_err().contains("not a checkpoint"));
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn checkpoint_steps_are_the_multiples_of_the_interval() {
        assert!(!is_checkpoint_step(0) && is_checkpoint_step(CHECKPOINT_EVERY) && !is_checkpoint_step(1));
        assert_eq!(checkpoint_step_at_or_below(CHECKPOINT_EVERY + 7), CHECKPOINT_EVERY);
        assert_eq!(checkpoint_step_at_or_below(5), 0);
        let mut kept = vec![1, 2];
        push_kept(&mut kept, 3, 2);
        assert_eq!(kept, vec![2, 3]);
    }
}
