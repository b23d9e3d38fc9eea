//! Every Zenoh key expression of the activity protocol, built in one place (`docs/protocol.md`
//! § Key layout). Nothing else formats a key.
//!
//! Every key starts with `<key-root>/<deployment>`: the deployment name is a key prefix, not a
//! Zenoh namespace. It is one key chunk without wildcards, so the keys of two deployments never
//! intersect — no subscriber, queryable, query or liveliness token of one matches a key of the
//! other, whatever the topology (peers, routers, several flights on one router) — and nothing
//! has to be checked at run time: isolation follows from building every key here. A prefix
//! is also visible wherever keys are (logs, `zenohd`'s admin space, `z_sub trace/**`), and a
//! system in another language needs no Zenoh configuration feature to join the right one.

use std::fmt;

/// The default key root: the first chunk(s) of every key, before the deployment.
pub const DEFAULT_ROOT: &str = "trace";

/// The deployment a process joins when none is configured (`--deployment`,
/// `TRACE_DEPLOYMENT`); `trace fly` gives each flight its own.
pub const DEFAULT_DEPLOYMENT: &str = "default";

/// A name used as one key chunk (server, action, goal id, role, telemetry channel) is not
/// usable in a key expression.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("`{name}` cannot be a key chunk: {reason}")]
pub struct BadChunk {
    /// The name.
    pub name: String,
    /// Why.
    pub reason: &'static str,
}

/// Checks that `name` is one non-empty key chunk without wildcards or verbatim marker.
pub fn check_chunk(name: &str) -> Result<(), BadChunk> {
    let reason = if name.is_empty() {
        "it is empty"
    } else if name.starts_with('@') {
        "it starts with `@` (reserved for verbatim chunks)"
    } else if name.contains(['/', '*', '$', '#', '?']) {
        "it contains one of / * $ # ?"
    } else if name.chars().any(char::is_whitespace) {
        "it contains white space"
    } else {
        return Ok(());
    };
    Err(BadChunk {
        name: name.to_owned(),
        reason,
    })
}

/// A goal id: `<mission>.<instance>.<token>.<attempt>` (stable across restarts, new per
/// attempt, one key chunk when the mission id is one).
pub fn goal_id(mission: &str, instance: u64, token: u64, attempt: u32) -> String {
    format!("{mission}.{instance}.{token}.{attempt}")
}

/// The attempt a goal id names (its last part; 1 if it has none).
pub fn goal_attempt(goal_id: &str) -> u32 {
    goal_id
        .rsplit('.')
        .next()
        .and_then(|a| a.parse().ok())
        .unwrap_or(1)
}

/// The key builder for one deployment under one root.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Keys {
    /// `<key-root>/<deployment>`: what every key starts with.
    root: String,
    deployment: String,
}

impl Default for Keys {
    /// Keys of the default deployment under the default root (`trace/default`).
    fn default() -> Self {
        Keys {
            root: format!("{DEFAULT_ROOT}/{DEFAULT_DEPLOYMENT}"),
            deployment: DEFAULT_DEPLOYMENT.to_owned(),
        }
    }
}

/// The protocol's primitives on one action, as named in `docs/protocol.md`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Channel {
    /// Queryable: send a goal.
    Goal,
    /// Queryable: cancel a goal.
    Cancel,
    /// Queryable: a goal's current state.
    State,
    /// Stream: status transitions.
    Status,
    /// Stream: feedback.
    Feedback,
    /// Stream: results.
    Result,
    /// Queryable (executive side): an operator's answer to a user task.
    Answer,
}

impl fmt::Display for Channel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Channel::Goal => "goal",
            Channel::Cancel => "cancel",
            Channel::State => "state",
            Channel::Status => "status",
            Channel::Feedback => "feedback",
            Channel::Result => "result",
            Channel::Answer => "answer",
        })
    }
}

impl Keys {
    /// Keys of the default deployment under `root` (one or more chunks, e.g. `trace` or
    /// `test/17`): `<root>/default/…`.
    pub fn new(root: &str) -> Result<Keys, BadChunk> {
        Keys::deployed(root, DEFAULT_DEPLOYMENT)
    }

    /// Keys of `deployment` (one chunk) under `root` (one or more chunks): every key starts
    /// with `<root>/<deployment>/`.
    pub fn deployed(root: &str, deployment: &str) -> Result<Keys, BadChunk> {
        for chunk in root.split('/') {
            check_chunk(chunk)?;
        }
        check_chunk(deployment)?;
        Ok(Keys {
            root: format!("{root}/{deployment}"),
            deployment: deployment.to_owned(),
        })
    }

    /// What every key starts with: `<key-root>/<deployment>`.
    pub fn root(&self) -> &str {
        &self.root
    }

    /// The deployment name.
    pub fn deployment(&self) -> &str {
        &self.deployment
    }

    /// `<root>/act/<server>/<action>/<channel>/<goal_id>` (goal, cancel, state).
    pub fn goal(&self, server: &str, action: &str, channel: Channel, goal_id: &str) -> String {
        format!("{}/act/{server}/{action}/{channel}/{goal_id}", self.root)
    }

    /// `<root>/act/<server>/<action>/<channel>/*`: what a server declares its queryables on.
    pub fn goal_queryable(&self, server: &str, action: &str, channel: Channel) -> String {
        format!("{}/act/{server}/{action}/{channel}/*", self.root)
    }

    /// `<root>/act/<server>/<action>/<channel>` (status, feedback, result).
    pub fn stream(&self, server: &str, action: &str, channel: Channel) -> String {
        format!("{}/act/{server}/{action}/{channel}", self.root)
    }

    /// `<root>/act/<server>/*/<channel>`: every action's stream of one kind on a server.
    pub fn streams_of(&self, server: &str, channel: Channel) -> String {
        format!("{}/act/{server}/*/{channel}", self.root)
    }

    /// `<root>/cat/<server>`: the server's catalogue queryable.
    pub fn catalogue(&self, server: &str) -> String {
        format!("{}/cat/{server}", self.root)
    }

    /// `<root>/alive/<role>/<instance>`: a process's liveliness token.
    pub fn alive(&self, role: &str, instance: &str) -> String {
        format!("{}/alive/{role}/{instance}", self.root)
    }

    /// `<root>/alive/act/<server>/<action>`: "this action is being served".
    pub fn alive_action(&self, server: &str, action: &str) -> String {
        format!("{}/alive/act/{server}/{action}", self.root)
    }

    /// `<root>/alive/act/<server>/<action>/<instance>`: "this action is being served by
    /// `instance`" — for servers of which several run at once (ground stations).
    pub fn alive_action_by(&self, server: &str, action: &str, instance: &str) -> String {
        format!("{}/alive/act/{server}/{action}/{instance}", self.root)
    }

    /// `<root>/alive/act/<server>/**`: every served action of a server, by any instance.
    pub fn alive_actions_of(&self, server: &str) -> String {
        format!("{}/alive/act/{server}/**", self.root)
    }

    /// `<root>/act/<server>/*/answer/<mission>.$*`: what an executive declares to receive the
    /// answers to its own user tasks (goal ids start with the mission id).
    pub fn answers_of(&self, server: &str, mission: &str) -> String {
        format!("{}/act/{server}/*/answer/{mission}.$*", self.root)
    }

    /// `<root>/fleet/<to>/message/<from>/<key>`: one message along a message flow into pool
    /// `to`, sent by the executive of pool `from` as a query; the reply is its receiver's
    /// verdict. The sender is a key chunk so that access control can let an executive send
    /// only as its own pool.
    pub fn fleet_message(&self, to: &str, from: &str, key: &str) -> String {
        format!("{}/fleet/{to}/message/{from}/{key}", self.root)
    }

    /// `<root>/fleet/<pool>/message/*/*`: what the executive running `pool` declares to
    /// receive its messages.
    pub fn fleet_inbox(&self, pool: &str) -> String {
        format!("{}/fleet/{pool}/message/*/*", self.root)
    }

    /// `<root>/fleet/<pool>/alive/<state>`: the liveliness token of the executive running
    /// `pool`, `running` while its part of the mission runs, `done` once it has ended and every
    /// message it sent was acknowledged.
    pub fn fleet_alive(&self, pool: &str, state: &str) -> String {
        format!("{}/fleet/{pool}/alive/{state}", self.root)
    }

    /// `<root>/fleet/*/alive/*`: every fleet executive's liveliness token.
    pub fn fleet_alive_all(&self) -> String {
        format!("{}/fleet/*/alive/*", self.root)
    }

    /// The pool and state named by a key under [`Keys::fleet_alive_all`].
    pub fn fleet_pool_of<'k>(&self, key: &'k str) -> Option<(&'k str, &'k str)> {
        let rest = key.strip_prefix(&self.root)?.strip_prefix("/fleet/")?;
        let (pool, tail) = rest.split_once('/')?;
        let state = tail.strip_prefix("alive/")?;
        (!state.contains('/')).then_some((pool, state))
    }

    /// The action named by a key under [`Keys::alive_actions_of`] or a stream key.
    pub fn action_of<'k>(&self, key: &'k str) -> Option<&'k str> {
        let rest = key.strip_prefix(&self.root)?.strip_prefix('/')?;
        let mut parts = rest.split('/');
        match (parts.next()?, parts.next()?) {
            ("alive", "act") => {
                parts.next()?;
                parts.next()
            }
            ("act", _) => parts.next(),
            _ => None,
        }
    }

    /// `<root>/tm/<source>/<channel>`: telemetry.
    pub fn telemetry(&self, source: &str, channel: &str) -> String {
        format!("{}/tm/{source}/{channel}", self.root)
    }

    /// `<root>/tm/<source>/*`: every telemetry channel of a source.
    pub fn telemetry_of(&self, source: &str) -> String {
        format!("{}/tm/{source}/*", self.root)
    }

    /// `<root>/exec/<mission>/record`: every execution-record line as it is written.
    pub fn exec_record(&self, mission: &str) -> String {
        format!("{}/exec/{mission}/record", self.root)
    }

    /// `<root>/exec/<mission>/model`: queryable, the mission model's BPMN XML as the executive
    /// loaded it (for views that draw the mission).
    pub fn exec_model(&self, mission: &str) -> String {
        format!("{}/exec/{mission}/model", self.root)
    }

    /// `<root>/exec/<mission>/history`: queryable, the execution record written so far.
    pub fn exec_history(&self, mission: &str) -> String {
        format!("{}/exec/{mission}/history", self.root)
    }

    /// `<root>/exec/<mission>/state`: queryable, the mission's current state.
    pub fn exec_state(&self, mission: &str) -> String {
        format!("{}/exec/{mission}/state", self.root)
    }

    /// `<root>/msg/<server>/<name>`: a notification pushed from the mission to a system.
    pub fn notification(&self, server: &str, name: &str) -> String {
        format!("{}/msg/{server}/{name}", self.root)
    }

    /// The last chunk of a key (the goal id of a goal/cancel/state key, the channel of a
    /// telemetry key).
    pub fn last_chunk(key: &str) -> &str {
        key.rsplit('/').next().unwrap_or(key)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_follow_the_documented_layout() {
        let k = Keys::default();
        assert_eq!(
            k.goal(
                "lander_sim",
                "excavation.excavate",
                Channel::Goal,
                "m.1.2.1"
            ),
            "trace/default/act/lander_sim/excavation.excavate/goal/m.1.2.1"
        );
        assert_eq!(
            k.stream("lander_sim", "arm.stow", Channel::Result),
            "trace/default/act/lander_sim/arm.stow/result"
        );
        assert_eq!(
            k.alive_action("lander_sim", "arm.stow"),
            "trace/default/alive/act/lander_sim/arm.stow"
        );
        assert_eq!(
            k.action_of("trace/default/alive/act/lander_sim/arm.stow"),
            Some("arm.stow")
        );
        assert_eq!(
            k.action_of("trace/default/act/lander_sim/arm.stow/status"),
            Some("arm.stow")
        );
        assert_eq!(
            k.action_of("trace/default/alive/act/ground/ground.approve_site/station-a"),
            Some("ground.approve_site")
        );
        assert_eq!(
            k.goal(
                "ground",
                "ground.approve_site",
                Channel::Answer,
                "m-1.1.2.1"
            ),
            "trace/default/act/ground/ground.approve_site/answer/m-1.1.2.1"
        );
        assert_eq!(
            k.answers_of("ground", "m-1"),
            "trace/default/act/ground/*/answer/m-1.$*"
        );
        assert_eq!(Keys::last_chunk("trace/default/act/s/a/goal/g1"), "g1");
        assert_eq!(goal_attempt(&goal_id("m-1", 1, 42, 3)), 3);
    }

    #[test]
    fn bad_chunks_are_named() {
        for bad in ["", "@adv", "a/b", "a*", "a$b", "a#", "a?", "a b"] {
            assert!(check_chunk(bad).is_err(), "{bad:?}");
        }
        assert!(check_chunk("excavation.excavate").is_ok());
        assert!(Keys::new("test/17").is_ok());
        assert!(Keys::new("test//17").is_err());
        assert!(Keys::deployed("trace", "a/b").is_err());
        assert!(Keys::deployed("trace", "*").is_err());
        assert!(Keys::deployed("trace", "").is_err());
    }

    #[test]
    fn every_key_carries_the_deployment_and_deployments_do_not_overlap() {
        let (a, b) = (
            Keys::deployed("trace", "flight-a").expect("a"),
            Keys::deployed("trace", "flight-b").expect("b"),
        );
        assert_eq!(a.root(), "trace/flight-a");
        assert_eq!(a.deployment(), "flight-a");
        assert_eq!(
            Keys::new("test/17").expect("root").root(),
            "test/17/default"
        );
        let keys = |k: &Keys| {
            vec![
                k.goal_queryable("ground", "ground.approve_site", Channel::Goal),
                k.streams_of("ground", Channel::Result),
                k.catalogue("ground"),
                k.alive("exec", "*"),
                k.alive_actions_of("ground"),
                k.answers_of("ground", "m"),
                k.telemetry_of("lander_sim"),
                k.exec_record("m"),
                k.exec_state("m"),
                k.notification("lander_sim", "n"),
            ]
        };
        // Every key of A, wildcards included, lies under A's prefix, which no key of B has.
        for key in keys(&a) {
            assert!(key.starts_with("trace/flight-a/"), "{key}");
        }
        for key in keys(&b) {
            assert!(key.starts_with("trace/flight-b/"), "{key}");
        }
        assert_eq!(b.action_of("trace/flight-a/alive/act/ground/x"), None);
    }
}
