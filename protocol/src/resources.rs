//! The iceoryx2 resources of a pipeline domain, as iceoryx2 itself lists them: the nodes named
//! `<domain>/<role>` and the services named `<domain>/<topic>`.
//!
//! iceoryx2 names its files after hashes (`iox2_<hash>…` in the shared-memory filesystem and in its
//! `iceoryx2/` temp folder), so a domain's resources cannot be found by file name; its own node and
//! service lists can. A launcher uses [`remove_dead_nodes`] after its children have exited (a killed
//! child leaves its node behind) and [`list`] to check that nothing of the domain is left.

use core::time::Duration;

use crate::services::Domain;
use iceoryx2::node::NodeView;
use iceoryx2::prelude::*;

/// A node of a domain.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, serde::Serialize)]
pub struct DomainNode {
    /// Its name, `<domain>/<role>`.
    pub name: String,
    /// `alive` or `dead` (dead: its process is gone without cleaning up).
    pub state: String,
    /// The process that created the node, when iceoryx2 can tell.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pid: Option<u32>,
}

/// What is left of a domain.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct DomainResources {
    /// Nodes of the domain.
    pub nodes: Vec<DomainNode>,
    /// Services of the domain (a topic is a pub/sub and an event service of the same name).
    pub services: Vec<String>,
}

impl DomainResources {
    /// Whether nothing of the domain is left.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty() && self.services.is_empty()
    }

    /// The processes of the alive nodes named `name`.
    pub fn alive_pids(&self, name: &str) -> Vec<u32> {
        self.nodes.iter().filter(|n| n.state == "alive" && n.name == name).filter_map(|n| n.pid).collect()
    }

    /// Nodes whose process is still running.
    pub fn alive_nodes(&self) -> impl Iterator<Item = &str> {
        self.nodes.iter().filter(|n| n.state == "alive").map(|n| n.name.as_str())
    }
}

fn in_domain(name: &str, domain: &Domain) -> bool {
    name.strip_prefix(domain.as_str()).is_some_and(|rest| rest.starts_with('/'))
}

/// The nodes and services of `domain` (nodes without readable details — another user's — are skipped).
pub fn list(domain: &Domain) -> Result<DomainResources, String> {
    let config = Config::global_config();
    let mut out = DomainResources::default();
    Node::<ipc::Service>::list(config, |state| {
        let (details, label, id) = match &state {
            NodeState::Alive(view) => (view.details().clone(), "alive", Some(*view.id())),
            NodeState::Dead(view) => (view.details().clone(), "dead", Some(*view.id())),
            NodeState::Inaccessible(_) | NodeState::Undefined(_) => (None, "", None),
        };
        if let Some(d) = details {
            let name = d.name().as_str().to_string();
            if in_domain(&name, domain) {
                let pid = id.and_then(|id| id.pid::<ipc::Service>().ok()).map(|p| p.value() as u32);
                out.nodes.push(DomainNode { name, state: label.to_string(), pid });
            }
        }
        CallbackProgression::Continue
    })
    .map_err(|e| format!("listing iceoryx2 nodes: {e:?}"))?;
    ipc::Service::list(config, |service| {
        let name = service.static_details.name().as_str();
        if in_domain(name, domain) && !out.services.iter().any(|s| s == name) {
            out.services.push(name.to_string());
        }
        CallbackProgression::Continue
    })
    .map_err(|e| format!("listing iceoryx2 services: {e:?}"))?;
    out.nodes.sort();
    out.services.sort();
    Ok(out)
}

/// Removes what dead processes left in `domain`: when no node of it is alive, the services a killed run
/// left half-created ([`remove_half_created_services`]), then the dead nodes' resources
/// ([`remove_dead_nodes`]). Returns the half-created services removed.
pub fn remove_leftovers(domain: &Domain) -> Result<Vec<String>, String> {
    let idle = list(domain)?.alive_nodes().next().is_none();
    let half = if idle { remove_half_created_services(domain)? } else { Vec::new() };
    remove_dead_nodes(domain)?;
    Ok(half)
}

/// Removes the stale resources of every dead node of `domain` (processes that died without cleaning up,
/// e.g. on SIGKILL), which also releases the services only they held. Returns how many were removed.
pub fn remove_dead_nodes(domain: &Domain) -> Result<usize, String> {
    let config = Config::global_config();
    let mut dead = Vec::new();
    // Every node iceoryx2 lists (alive, dead or not readable): the unlisted sweep leaves them alone.
    let mut listed = Vec::new();
    Node::<ipc::Service>::list(config, |state| {
        // A node whose owner died before it wrote its details (killed during its creation) belongs to no
        // domain that can be read, and to no live process: it is removed too.
        match state {
            NodeState::Dead(view) => {
                listed.push(view.id().value().to_string());
                if view.details().as_ref().is_none_or(|d| in_domain(d.name().as_str(), domain)) {
                    dead.push(view)
                }
            }
            NodeState::Alive(view) => listed.push(view.id().value().to_string()),
            NodeState::Inaccessible(id) | NodeState::Undefined(id) => listed.push(id.value().to_string()),
        }
        CallbackProgression::Continue
    })
    .map_err(|e| format!("listing iceoryx2 nodes: {e:?}"))?;
    let node_dir = std::path::PathBuf::from(config.global.node_dir().to_string());
    let mut removed = 0;
    for view in dead {
        let id = view.id().value();
        match view.blocking_remove_stale_resources(Duration::from_secs(1)) {
            Ok(()) => removed += 1,
            // A node killed in the middle of its creation (or of its own clean-up) can leave files
            // iceoryx2's clean-up stops at: its directory is removed instead, and the run goes on — one
            // dead node is never a reason to give up the domain.
            Err(e) => {
                let dir = node_dir.join(id.to_string());
                match std::fs::remove_dir_all(&dir) {
                    Ok(()) => removed += 1,
                    Err(io) if io.kind() == std::io::ErrorKind::NotFound => removed += 1,
                    Err(io) => crate::log_line!(
                        "warning: the resources of a dead iceoryx2 node ({}) could not be removed ({e:?}; {io}); \
                         going on",
                        dir.display()
                    ),
                }
            }
        }
    }
    Ok(removed + remove_unlisted_node_dirs(&node_dir, domain, &listed))
}

/// Removes the node directories of `domain` that iceoryx2 does not list at all — a node killed after it
/// wrote its details but before its liveness token, which leaves `iox2_node.details` without it — when
/// they are older than [`UNLISTED_NODE_AFTER`] (a node being created now is left alone) and not in
/// `listed` (the nodes iceoryx2 lists, which its own clean-up handles). Returns how many.
fn remove_unlisted_node_dirs(node_dir: &std::path::Path, domain: &Domain, listed: &[String]) -> usize {
    let prefix = format!("{}/", domain.as_str());
    let mut removed = 0;
    for entry in std::fs::read_dir(node_dir).into_iter().flatten().flatten() {
        let dir = entry.path();
        let Some(id) = dir.file_name().and_then(|n| n.to_str()).map(str::to_string) else { continue };
        if listed.contains(&id) {
            continue;
        }
        let Ok(details) = std::fs::read(dir.join("iox2_node.details")) else { continue };
        let ours = details.windows(prefix.len()).any(|w| w == prefix.as_bytes());
        let old = entry
            .metadata()
            .and_then(|m| m.modified())
            .is_ok_and(|t| t.elapsed().is_ok_and(|a| a >= UNLISTED_NODE_AFTER));
        if ours && old && std::fs::remove_dir_all(&dir).is_ok() {
            removed += 1;
        }
    }
    removed
}

/// How old an unlisted node directory must be to count as left by a node killed in its creation (creating
/// a node takes microseconds to a few milliseconds).
pub const UNLISTED_NODE_AFTER: Duration = Duration::from_millis(200);

/// How long a service may be in creation before it counts as left half-created (creating one takes
/// microseconds; a creator killed mid-way never finishes it).
pub const HALF_CREATED_AFTER: Duration = Duration::from_secs(1);

/// The static config file of the iceoryx2 service `name` (`<root>/<services>/<prefix><hash><suffix>`; one
/// per messaging pattern: a topic is a pub/sub and an event service of one name). iceoryx2 names it after a
/// hash of the pattern and the name, so it can be found even when it holds nothing yet.
pub fn static_config_files(name: &str) -> Result<[std::path::PathBuf; 2], String> {
    use iceoryx2::service::messaging_pattern::MessagingPattern;
    use iceoryx2::service::service_hash::ServiceHash;
    type Hasher = <ipc::Service as iceoryx2::service::Service>::ServiceNameHasher;

    let global = &Config::global_config().global;
    let dir = std::path::PathBuf::from(global.service_dir().to_string());
    let (prefix, suffix) = (global.prefix.to_string(), global.service.static_config_storage_suffix.to_string());
    let service = ServiceName::new(name).map_err(|e| format!("service name {name}: {e:?}"))?;
    Ok([MessagingPattern::PublishSubscribe, MessagingPattern::Event]
        .map(|p| dir.join(format!("{prefix}{}{suffix}", ServiceHash::new::<Hasher>(&service, p).as_str()))))
}

/// Removes the services of `domain` left *half-created* — their static config file still has the
/// owner-read-write permissions iceoryx2 gives it while it writes it (it makes the file read-only when
/// done) — by a process killed while creating them (kill -9 of a launch and its children).
/// Opening such a service fails with `HangsInCreation` for ever, and so does iceoryx2's dead-node
/// clean-up, which opens the services of the dead nodes. Only for a domain nobody uses (the caller holds
/// the domain's lock and found no live node); files younger than [`HALF_CREATED_AFTER`] are left alone.
/// Returns the services removed.
pub fn remove_half_created_services(domain: &Domain) -> Result<Vec<String>, String> {
    use std::os::unix::fs::PermissionsExt;

    let mut removed = Vec::new();
    for (_, name) in crate::services::all(domain) {
        for file in static_config_files(&name)? {
            let Ok(meta) = std::fs::metadata(&file) else { continue };
            let in_creation = meta.permissions().mode() & 0o777 == 0o600;
            let old = meta.modified().ok().and_then(|t| t.elapsed().ok()).is_some_and(|age| age >= HALF_CREATED_AFTER);
            if in_creation && old {
                std::fs::remove_file(&file).map_err(|e| format!("removing {}: {e}", file.display()))?;
                if removed.last() != Some(&name) {
                    removed.push(name.clone());
                }
            }
        }
    }
    Ok(removed)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn domain_prefix_needs_the_separator() {
        let d = Domain::new("run-1").unwrap();
        assert!(in_domain("run-1/estimator", &d));
        assert!(!in_domain("run-12/estimator", &d));
        assert!(!in_domain("run-1", &d));
    }
}

#[cfg(test)]
mod unlisted_tests {
    use super::*;

    /// A node directory of the domain holding only its details, older than the guard, is removed; a
    /// young one (a node being created), another domain's and a live node's are not.
    #[test]
    fn a_node_killed_before_its_liveness_token_is_removed() {
        let root = std::env::temp_dir().join(format!("uavloc-nodes-test-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        let domain = Domain::new("lab-dead").unwrap();
        let make = |id: &str, name: &str, age_s: u64| {
            let dir = root.join(id);
            std::fs::create_dir_all(&dir).unwrap();
            std::fs::write(dir.join("iox2_node.details"), format!("name = \"{name}\"")).unwrap();
            let t = std::time::SystemTime::now() - Duration::from_secs(age_s);
            std::fs::File::open(&dir).unwrap().set_modified(t).unwrap();
        };
        make("1", "lab-dead/estimator", 10);
        make("2", "lab-dead/planner", 0);
        make("3", "other/estimator", 10);
        make("4", "lab-dead/monitor", 10);
        assert_eq!(remove_unlisted_node_dirs(&root, &domain, &["4".to_string()]), 1);
        assert!(!root.join("1").exists());
        assert!(root.join("2").exists() && root.join("3").exists() && root.join("4").exists());
        std::fs::remove_dir_all(&root).unwrap();
    }
}
