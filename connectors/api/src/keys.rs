//! Every Zenoh key expression of the activity protocol, built in one place (`docs/protocol.md`
//! § Key layout). Nothing else formats a key.

use std::fmt;

/// The root of every key (a deployment may run several missions side by side under different
/// roots, e.g. one per test).
pub const DEFAULT_ROOT: &str = "trace";

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

/// The key builder for one root.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Keys {
    root: String,
}

impl Default for Keys {
    fn default() -> Self {
        Keys {
            root: DEFAULT_ROOT.to_owned(),
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
    /// Keys under `root` (one or more chunks, e.g. `trace` or `test/17`).
    pub fn new(root: &str) -> Result<Keys, BadChunk> {
        for chunk in root.split('/') {
            check_chunk(chunk)?;
        }
        Ok(Keys {
            root: root.to_owned(),
        })
    }

    /// The root.
    pub fn root(&self) -> &str {
        &self.root
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
            "trace/act/lander_sim/excavation.excavate/goal/m.1.2.1"
        );
        assert_eq!(
            k.stream("lander_sim", "arm.stow", Channel::Result),
            "trace/act/lander_sim/arm.stow/result"
        );
        assert_eq!(
            k.alive_action("lander_sim", "arm.stow"),
            "trace/alive/act/lander_sim/arm.stow"
        );
        assert_eq!(
            k.action_of("trace/alive/act/lander_sim/arm.stow"),
            Some("arm.stow")
        );
        assert_eq!(
            k.action_of("trace/act/lander_sim/arm.stow/status"),
            Some("arm.stow")
        );
        assert_eq!(
            k.action_of("trace/alive/act/ground/ground.approve_site/station-a"),
            Some("ground.approve_site")
        );
        assert_eq!(
            k.goal(
                "ground",
                "ground.approve_site",
                Channel::Answer,
                "m-1.1.2.1"
            ),
            "trace/act/ground/ground.approve_site/answer/m-1.1.2.1"
        );
        assert_eq!(
            k.answers_of("ground", "m-1"),
            "trace/act/ground/*/answer/m-1.$*"
        );
        assert_eq!(Keys::last_chunk("trace/act/s/a/goal/g1"), "g1");
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
    }
}
