//! The catalogues the connected systems serve, live over Zenoh: the studio joins the network
//! as the deployment's other processes do (the same `ZenohArgs`), announces itself as a monitor
//! (`<root>/alive/monitor/studio-<pid>`), and asks every server's catalogue queryable
//! (`<root>/cat/*`) when the page asks for the catalogues and whenever a served action
//! appears or goes (`<root>/alive/act/**`). A live catalogue wins over a file of the same
//! server; a server that stops answering falls back to its file, if any. The same membership
//! follows the running missions for the operations view ([`crate::ops`]).

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use connector_api::{Catalogue, Keys, wire};
use connector_zenoh::{Role, ZenohArgs};
use zenoh::query::{ConsolidationMode, QueryTarget};

/// How long one round of catalogue queries waits for answers.
const ASK_FOR: Duration = Duration::from_secs(2);

/// Why the studio could not join Zenoh.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    /// The configuration or the session.
    #[error(transparent)]
    Session(#[from] connector_zenoh::SessionError),
    /// A declaration failed.
    #[error("zenoh: {0}")]
    Zenoh(String),
}

/// The studio's Zenoh membership and the catalogues it has heard.
pub struct Live {
    session: zenoh::Session,
    keys: Keys,
    heard: Arc<Mutex<BTreeMap<String, Catalogue>>>,
    executives: Arc<Mutex<BTreeMap<String, crate::ops::Presence>>>,
    books: Mutex<crate::ops::Books>,
    _token: zenoh::liveliness::LivelinessToken,
    _watch: zenoh::pubsub::Subscriber<()>,
    _executives: zenoh::pubsub::Subscriber<()>,
}

impl std::fmt::Debug for Live {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Live")
            .field("root", &self.keys.root())
            .finish()
    }
}

impl Live {
    /// Opens the session (as a spoke unless the flags say otherwise) and starts watching the
    /// served actions; asks for the catalogues once before returning.
    pub async fn join(zenoh: &ZenohArgs) -> Result<Arc<Live>, LiveError> {
        let session = zenoh.open(Role::Spoke).await?;
        let keys = zenoh.keys()?;
        let z = |e: zenoh::Error| LiveError::Zenoh(e.to_string());
        let token = session
            .liveliness()
            // A studio announces itself as a monitor: that is what it does on the network
            // (what access control lets a monitor's certificate declare).
            .declare_token(keys.alive("monitor", &format!("studio-{}", std::process::id())))
            .await
            .map_err(z)?;
        let (changed_tx, mut changed) = tokio::sync::mpsc::unbounded_channel::<()>();
        let watch = session
            .liveliness()
            .declare_subscriber(format!("{}/alive/act/**", keys.root()))
            .callback(move |_| {
                let _ = changed_tx.send(());
            })
            .await
            .map_err(z)?;
        // The executives, from the tokens already declared on.
        let executives: Arc<Mutex<BTreeMap<String, crate::ops::Presence>>> = Arc::default();
        let prefix = format!("{}/alive/exec/", keys.root());
        let seen = Arc::clone(&executives);
        let watch_executives = session
            .liveliness()
            .declare_subscriber(format!("{prefix}*"))
            .history(true)
            .callback(move |s| {
                let mission = s.key_expr().as_str().trim_start_matches(&prefix);
                let alive = s.kind() == zenoh::sample::SampleKind::Put;
                tracing::info!(mission, alive, "executive");
                if let Ok(mut m) = seen.lock() {
                    crate::ops::seen(&mut m, mission, alive);
                }
            })
            .await
            .map_err(z)?;
        let live = Arc::new(Live {
            session,
            keys,
            heard: Arc::default(),
            executives,
            books: Mutex::default(),
            _token: token,
            _watch: watch,
            _executives: watch_executives,
        });
        live.ask().await;
        let weak = Arc::downgrade(&live);
        tokio::spawn(async move {
            while changed.recv().await.is_some() {
                // A server declares its actions one by one: ask once they have settled.
                tokio::time::sleep(Duration::from_millis(200)).await;
                while changed.try_recv().is_ok() {}
                let Some(live) = weak.upgrade() else { break };
                live.ask().await;
            }
        });
        Ok(live)
    }

    /// Asks every server for its catalogue; what answers replaces what was heard before.
    pub async fn ask(&self) {
        let key = self.keys.catalogue("*");
        let replies = match self
            .session
            .get(&key)
            .target(QueryTarget::All)
            .consolidation(ConsolidationMode::None)
            .timeout(ASK_FOR)
            .with(connector_zenoh::replies())
            .await
        {
            Ok(r) => r,
            Err(e) => {
                tracing::warn!(%key, error = %e, "cannot ask for the catalogues");
                return;
            }
        };
        let mut heard = BTreeMap::new();
        while let Ok(reply) = replies.recv_async().await {
            let Ok(sample) = reply.result() else { continue };
            let at = sample.key_expr().as_str().to_owned();
            match wire::parse::<Catalogue>("catalogue", &at, &sample.payload().to_bytes()) {
                // A catalogue comes on its own server's key, never another's.
                Ok(cat)
                    if connector_api::keys::check_chunk(&cat.server).is_ok()
                        && at == self.keys.catalogue(&cat.server) =>
                {
                    heard.insert(cat.server.clone(), cat);
                }
                Ok(cat) => {
                    tracing::warn!(%at, server = %cat.server, "a catalogue on another server's key was ignored")
                }
                Err(e) => tracing::warn!("{e}"),
            }
        }
        tracing::debug!(servers = ?heard.keys().collect::<Vec<_>>(), "catalogues heard");
        if let Ok(mut h) = self.heard.lock() {
            *h = heard;
        }
    }

    /// The studio's Zenoh session.
    pub fn session(&self) -> &zenoh::Session {
        &self.session
    }

    /// The key builder of its deployment.
    pub fn keys(&self) -> &Keys {
        &self.keys
    }

    pub(crate) fn executives_seen(&self) -> &Mutex<BTreeMap<String, crate::ops::Presence>> {
        &self.executives
    }

    pub(crate) fn books(&self) -> std::sync::MutexGuard<'_, crate::ops::Books> {
        self.books.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// The catalogues heard in the last round.
    pub fn heard(&self) -> Vec<Catalogue> {
        self.heard
            .lock()
            .map(|h| h.values().cloned().collect())
            .unwrap_or_default()
    }
}
