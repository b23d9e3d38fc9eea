//! Presence: the per-action liveliness tokens. A goal for an action nobody serves waits for
//! its token; a server that vanishes gets `grace` to come back before its goals fail with
//! `CONNECTOR_LOST`; one that comes back has every goal in flight reconciled.

use super::*;

impl Shared {
    /// Liveliness of one action changed.
    pub(super) fn on_liveliness(self: &Arc<Shared>, sample: &Sample) {
        let key = sample.key_expr().as_str();
        let Some(action) = self.opts.keys.action_of(key).map(str::to_owned) else {
            return;
        };
        let mut s = self.state();
        let generation = {
            let g = s.generation.entry(action.clone()).or_default();
            *g += 1;
            *g
        };
        match sample.kind() {
            SampleKind::Put => {
                tracing::info!(connector = self.name(), action, key, "action served");
                s.alive
                    .entry(action.clone())
                    .or_default()
                    .insert(key.to_owned());
                let (sent, unsent): (Vec<_>, Vec<_>) = s
                    .flights
                    .values()
                    .filter(|f| f.command.action == action)
                    .map(|f| (f.acked, f.command.clone()))
                    .partition(|(acked, _)| *acked);
                let cancels: Vec<String> = s
                    .cancels
                    .iter()
                    .filter(|(_, a)| **a == action)
                    .map(|(g, _)| g.clone())
                    .collect();
                drop(s);
                for (_, c) in unsent {
                    self.start_sending(&c.goal_id);
                }
                for (_, c) in sent {
                    self.rt.spawn(Arc::clone(self).reconcile(c));
                }
                for g in cancels {
                    self.rt
                        .spawn(Arc::clone(self).cancel(g, action.clone(), None));
                }
            }
            SampleKind::Delete => {
                tracing::warn!(
                    connector = self.name(),
                    action,
                    key,
                    "action no longer served"
                );
                if let Some(tokens) = s.alive.get_mut(&action) {
                    tokens.remove(key);
                }
                let running =
                    !s.served(&action) && s.flights.values().any(|f| f.command.action == action);
                drop(s);
                if running {
                    self.start_grace(action, generation);
                }
            }
        }
    }

    /// After the grace period, goals of an action still unserved fail with `CONNECTOR_LOST`.
    pub(super) fn start_grace(self: &Arc<Shared>, action: String, generation: u64) {
        let me = Arc::clone(self);
        let grace = Duration::from_millis(self.opts.config.grace_ms);
        self.rt.spawn(async move {
            tokio::time::sleep(grace).await;
            let lost: Vec<String> = {
                let mut s = me.state();
                if s.served(&action) || s.generation.get(&action) != Some(&generation) {
                    return;
                }
                let ids: Vec<String> = s
                    .flights
                    .iter()
                    .filter(|(_, f)| f.command.action == action)
                    .map(|(id, _)| id.clone())
                    .collect();
                for id in &ids {
                    s.land(id, Ended::Reported);
                }
                ids
            };
            for id in lost {
                me.fail(
                    &id,
                    codes::CONNECTOR_LOST,
                    format!(
                        "`{}` stopped serving `{action}` and did not return within {} ms",
                        me.server(),
                        grace.as_millis()
                    ),
                );
            }
        });
    }
}
