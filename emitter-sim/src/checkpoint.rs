//! emitter-sim's `--checkpoint` file: the world snapshots a restarted emitter-sim flies on from (see
//! [`runtime::recovery`] for when they are taken and why the oldest is used).

use std::path::Path;

use model::Scenario;
use protocol::services::Domain;
use runtime::ProcessError;
use runtime::recovery::{self, EMITTER_SNAPSHOTS};

use model::world::{Snapshot, World};

/// What emitter-sim writes to its `--checkpoint` file: the last world snapshots (oldest first), each with
/// whether the command of the step before it was missed.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Saved {
    /// The run's scenario ([`model::Scenario::fingerprint`]): a snapshot of another run is refused.
    pub scenario: String,
    /// At most [`EMITTER_SNAPSHOTS`], one every [`recovery::SNAPSHOT_EVERY`] steps.
    pub snapshots: Vec<(Snapshot, bool)>,
}

/// Where a (re)started emitter-sim begins.
pub struct Start {
    /// The world at `step`.
    pub world: World,
    /// The first step to publish: 0, or the oldest snapshot's after a restart.
    pub step: u64,
    /// Whether the command of the step before `step` was missed.
    pub missed: bool,
    /// The snapshots kept so far (written again with each new one).
    pub snapshots: Vec<(Snapshot, bool)>,
}

/// A restart in the same run flies on from the oldest snapshot of its `checkpoint` file; a new run (no
/// file, or no full set of snapshots yet) from step 0. A file of another run, or a snapshot that does not
/// fit the scenario, is refused (exit 2).
pub fn start(checkpoint: Option<&Path>, domain: &Domain, scenario: &Scenario) -> Result<Start, ProcessError> {
    let saved = match checkpoint {
        Some(path) => recovery::load::<Saved>(path, crate::ROLE, domain.as_str())
            .map_err(|e| ProcessError::input_because("--checkpoint", e))?,
        None => None,
    };
    // A snapshot of another run (another scenario, steps or seed) would fly this run from that one's world.
    if let (Some(path), Some(saved)) = (checkpoint, &saved)
        && saved.scenario != scenario.fingerprint()
    {
        return Err(ProcessError::Input(format!(
            "--checkpoint {}: the snapshots of another run (another scenario, steps or seed); give this run's \
             checkpoint, or a file that does not exist yet for a new run",
            path.display()
        )));
    }
    let snapshots: Vec<(Snapshot, bool)> = saved.map(|s| s.snapshots).unwrap_or_default();
    // Only a full set goes far enough back for every step the monitor may lack (see runtime::recovery).
    let oldest = snapshots.first().filter(|_| snapshots.len() >= EMITTER_SNAPSHOTS);
    let (world, start_step, start_missed) = match oldest {
        Some((snapshot, missed)) => (
            World::restore(scenario, snapshot).map_err(|e| {
                ProcessError::input_because("--checkpoint: a snapshot that does not fit the scenario", e)
            })?,
            snapshot.step,
            *missed,
        ),
        None => (World::from_scenario(scenario).map_err(|e| ProcessError::input_because("scenario", e))?, 0, false),
    };
    if start_step > scenario.steps as u64 {
        return Err(ProcessError::Input(format!(
            "--checkpoint: its snapshot is of step {start_step}, beyond the run's {} steps",
            scenario.steps
        )));
    }
    Ok(Start { world, step: start_step, missed: start_missed, snapshots })
}

/// Writes the `snapshots` of the run of scenario `fingerprint` to `path`.
pub fn save(path: &Path, domain: &Domain, fingerprint: &str, snapshots: &[(Snapshot, bool)]) -> Result<(), String> {
    let saved = Saved { scenario: fingerprint.to_string(), snapshots: snapshots.to_vec() };
    recovery::save(path, crate::ROLE, domain.as_str(), &saved)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The snapshots of a world flown straight on at its headings: one after each of `steps` steps.
    fn flown(scenario: &Scenario, steps: u64) -> Vec<Snapshot> {
        let mut world = World::from_scenario(scenario).unwrap();
        (0..steps)
            .map(|_| {
                let keep = world.headings().to_vec();
                world.apply(&keep).unwrap();
                world.snapshot()
            })
            .collect()
    }

    #[test]
    fn a_restart_flies_on_from_the_oldest_of_a_full_set_of_snapshots() {
        let dir = std::env::temp_dir().join(format!("uavloc-ckpt-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("emitter-sim.ckpt");
        let _ = std::fs::remove_file(&path);
        let domain = Domain::new("ckpt").unwrap();
        let sc = Scenario { steps: 40, ..Scenario::default() };
        // No file: a new run from step 0.
        let s = start(Some(&path), &domain, &sc).unwrap();
        assert_eq!((s.step, s.missed, s.snapshots.len()), (0, false, 0));
        assert_eq!(s.world.snapshot(), World::from_scenario(&sc).unwrap().snapshot());
        let snaps = flown(&sc, 9);
        // One snapshot is not enough to go back far enough: step 0 again, the snapshot kept.
        save(&path, &domain, &sc.fingerprint(), &[(snaps[3].clone(), false)]).unwrap();
        let s = start(Some(&path), &domain, &sc).unwrap();
        assert_eq!((s.step, s.snapshots.len()), (0, 1));
        // A full set: the world of the oldest, exactly as it was, with its missed flag.
        let set = [(snaps[3].clone(), true), (snaps[8].clone(), false)];
        assert_eq!(set.len(), EMITTER_SNAPSHOTS);
        save(&path, &domain, &sc.fingerprint(), &set).unwrap();
        let s = start(Some(&path), &domain, &sc).unwrap();
        assert_eq!((s.step, s.missed), (snaps[3].step, true));
        assert_eq!(s.world.snapshot(), snaps[3]);
        assert_eq!(s.snapshots, set.to_vec());
        // Another run (another seed): refused, not flown.
        let other = Scenario { seed: sc.seed + 1, ..sc.clone() };
        let e = start(Some(&path), &domain, &other).err().unwrap();
        assert!(matches!(&e, ProcessError::Input(m) if m.contains("another run")), "{e}");
        // A snapshot beyond the run's steps (the same scenario cut shorter is another run: its fingerprint
        // differs, so it is written as this run's to reach the check).
        let short = Scenario { steps: 2, ..sc.clone() };
        save(&path, &domain, &short.fingerprint(), &set).unwrap();
        let e = start(Some(&path), &domain, &short).err().unwrap();
        assert!(matches!(&e, ProcessError::Input(m) if m.contains("beyond the run")), "{e}");
        // Another domain's file: refused as bad input, the loader's reason kept as the cause.
        let e = start(Some(&path), &Domain::new("elsewhere").unwrap(), &sc).err().unwrap();
        assert!(matches!(&e, ProcessError::InputBecause { context, .. } if context == "--checkpoint"), "{e:?}");
        assert_eq!(e.code(), 2);
        assert!(std::error::Error::source(&e).is_some());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
