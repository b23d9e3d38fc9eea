//! Opening Zenoh the same way in every TRACE binary: Zenoh's own JSON5 configuration file if
//! given, else the embedded defaults (peer mode on loopback, multicast scouting off), then the
//! usual endpoint and scouting flags on top.

use std::path::PathBuf;

use connector_api::Keys;

/// The loopback endpoint the executive listens on by default and every other process connects
/// to, so a one-host mission needs no router and no configuration.
pub const DEFAULT_HUB: &str = "tcp/127.0.0.1:7447";

/// How often a lost connection is tried again in the embedded defaults: from 20 ms, growing
/// by half each time, at most every 200 ms.
const CONNECT_RETRY: &str =
    "{ period_init_ms: 20, period_max_ms: 200, period_increase_factor: 1.5 }";

/// The environment variable naming the deployment when `--deployment` is not given.
const DEPLOYMENT_ENV: &str = "TRACE_DEPLOYMENT";

/// Zenoh flags shared by every binary.
#[derive(clap::Args, Clone, Debug, Default)]
pub struct ZenohArgs {
    /// Zenoh configuration file (JSON5, Zenoh's own format; see deploy/zenoh/).
    #[arg(long = "zenoh-config", value_name = "FILE")]
    pub zenoh_config: Option<PathBuf>,
    /// Zenoh mode: peer, client or router.
    #[arg(long = "mode", value_name = "MODE")]
    pub mode: Option<String>,
    /// Endpoint to connect to (repeatable), e.g. tcp/10.0.0.2:7447.
    #[arg(short = 'e', long = "connect", value_name = "ENDPOINT")]
    pub connect: Vec<String>,
    /// Endpoint to listen on (repeatable), e.g. tcp/127.0.0.1:7447.
    #[arg(short = 'l', long = "listen", value_name = "ENDPOINT")]
    pub listen: Vec<String>,
    /// Disable UDP multicast scouting (off already in the embedded defaults).
    #[arg(long)]
    pub no_multicast_scouting: bool,
    /// Enable UDP multicast scouting.
    #[arg(long, conflicts_with = "no_multicast_scouting")]
    pub multicast_scouting: bool,
    /// One key of Zenoh's configuration, set after the file and the other flags (repeatable):
    /// `KEY=VALUE` with VALUE in JSON5, e.g.
    /// `--zenoh-set 'transport/link/tls/root_ca_certificate="certs/ca.pem"'`.
    #[arg(long = "zenoh-set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Root of every key expression, before the deployment name.
    #[arg(long = "key-root", value_name = "ROOT", default_value = connector_api::keys::DEFAULT_ROOT)]
    pub root: String,
    /// The deployment this process belongs to: one key chunk after the key root, so every key
    /// is `<key-root>/<deployment>/…` and processes of other deployments never see or offer
    /// anything (default: `$TRACE_DEPLOYMENT`, else `default`).
    #[arg(long = "deployment", value_name = "NAME")]
    pub deployment: Option<String>,
}

/// Why Zenoh could not be opened.
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    /// The configuration file or a flag is invalid.
    #[error("zenoh configuration: {0}")]
    Config(String),
    /// Opening the session failed.
    #[error("cannot open zenoh: {0}")]
    Open(String),
    /// The key root is not usable.
    #[error(transparent)]
    Root(#[from] connector_api::keys::BadChunk),
}

/// Which side of the embedded default topology a process is on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    /// Listens on [`DEFAULT_HUB`] (the executive).
    Hub,
    /// Connects to [`DEFAULT_HUB`] (simulator, ground station, monitors).
    Spoke,
}

impl ZenohArgs {
    /// The Zenoh configuration these flags describe.
    pub fn config(&self, role: Role) -> Result<zenoh::Config, SessionError> {
        let bad = |e: zenoh::Error| SessionError::Config(e.to_string());
        let mut c = match &self.zenoh_config {
            Some(path) => zenoh::Config::from_file(path)
                .map_err(|e| SessionError::Config(format!("{}: {e}", path.display())))?,
            None => {
                let mut c = zenoh::Config::default();
                c.insert_json5("mode", "\"peer\"").map_err(bad)?;
                c.insert_json5("scouting/multicast/enabled", "false")
                    .map_err(bad)?;
                // A process whose peer went away (an executive restarting) tries again soon and
                // often, not on Zenoh's default 1 s growing to 4 s: on the embedded topology the
                // peers are a loopback hop apart, and a restarted executive should have its
                // systems back within a fraction of a second.
                c.insert_json5("connect/retry", CONNECT_RETRY)
                    .map_err(bad)?;
                if self.listen.is_empty() && self.connect.is_empty() {
                    let (listen, connect): (&[&str], &[&str]) = match role {
                        Role::Hub => (&[DEFAULT_HUB], &[]),
                        Role::Spoke => (&[], &[DEFAULT_HUB]),
                    };
                    c.insert_json5("listen/endpoints", &json(listen))
                        .map_err(bad)?;
                    c.insert_json5("connect/endpoints", &json(connect))
                        .map_err(bad)?;
                }
                c
            }
        };
        if let Some(mode) = &self.mode {
            if !matches!(mode.as_str(), "peer" | "client" | "router") {
                return Err(SessionError::Config(format!(
                    "--mode {mode}: expected peer, client or router"
                )));
            }
            c.insert_json5("mode", &format!("\"{mode}\""))
                .map_err(bad)?;
        }
        if !self.listen.is_empty() {
            c.insert_json5("listen/endpoints", &json(&self.listen))
                .map_err(bad)?;
        }
        if !self.connect.is_empty() {
            c.insert_json5("connect/endpoints", &json(&self.connect))
                .map_err(bad)?;
        }
        if self.no_multicast_scouting || self.multicast_scouting {
            c.insert_json5(
                "scouting/multicast/enabled",
                if self.multicast_scouting {
                    "true"
                } else {
                    "false"
                },
            )
            .map_err(bad)?;
        }
        for item in &self.set {
            let Some((key, value)) = item.split_once('=') else {
                return Err(SessionError::Config(format!(
                    "--zenoh-set {item}: expected KEY=VALUE"
                )));
            };
            c.insert_json5(key.trim(), value.trim())
                .map_err(|e| SessionError::Config(format!("--zenoh-set {item}: {e}")))?;
        }
        Ok(c)
    }

    /// The deployment name: `--deployment`, else `TRACE_DEPLOYMENT`, else `default`.
    pub fn deployment(&self) -> String {
        self.deployment
            .clone()
            .or_else(|| std::env::var(DEPLOYMENT_ENV).ok().filter(|d| !d.is_empty()))
            .unwrap_or_else(|| connector_api::keys::DEFAULT_DEPLOYMENT.to_owned())
    }

    /// The key builder for `--key-root` and the deployment.
    pub fn keys(&self) -> Result<Keys, SessionError> {
        Ok(Keys::deployed(&self.root, &self.deployment())?)
    }

    /// Opens the session.
    pub async fn open(&self, role: Role) -> Result<zenoh::Session, SessionError> {
        let config = self.config(role)?;
        zenoh::open(config)
            .await
            .map_err(|e| SessionError::Open(e.to_string()))
    }
}

/// Logging for system processes: to stderr, `RUST_LOG` or warnings (Zenoh's own only if
/// errors).
pub fn log_to_stderr() {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn,zenoh=error")),
        )
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .with_writer(std::io::stderr)
        .init();
}

fn json<S: AsRef<str>>(items: &[S]) -> String {
    serde_json::to_string(&items.iter().map(AsRef::as_ref).collect::<Vec<_>>())
        .unwrap_or_else(|_| "[]".to_owned())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shipped_zenoh_configurations_parse() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../deploy/zenoh");
        let mut n = 0;
        let mut dirs = vec![dir];
        while let Some(dir) = dirs.pop() {
            for entry in std::fs::read_dir(&dir).expect("deploy/zenoh") {
                let path = entry.expect("entry").path();
                if path.is_dir() {
                    dirs.push(path);
                    continue;
                }
                let args = ZenohArgs {
                    zenoh_config: Some(path.clone()),
                    ..ZenohArgs::default()
                };
                args.config(Role::Spoke)
                    .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                n += 1;
            }
        }
        assert!(n >= 9, "{n} files");
    }

    #[test]
    fn the_embedded_defaults_retry_lost_connections_soon() {
        let c = ZenohArgs::default().config(Role::Spoke).expect("defaults");
        let retry = c.get_json("connect/retry").expect("set");
        assert!(retry.contains(r#""period_init_ms":20"#), "{retry}");
        assert_eq!(
            c.get_json("connect/endpoints").expect("set"),
            format!("[\"{DEFAULT_HUB}\"]")
        );
    }

    #[test]
    fn flags_override_and_bad_values_are_named() {
        let args = ZenohArgs {
            mode: Some("satellite".into()),
            ..ZenohArgs::default()
        };
        let e = args.config(Role::Hub).unwrap_err().to_string();
        assert!(e.contains("--mode satellite"), "{e}");
        let args = ZenohArgs {
            zenoh_config: Some("/nonexistent.json5".into()),
            ..ZenohArgs::default()
        };
        assert!(
            args.config(Role::Hub)
                .unwrap_err()
                .to_string()
                .contains("/nonexistent.json5")
        );
        let args = ZenohArgs {
            set: vec!["transport/link/tx/lease=2500".into()],
            ..ZenohArgs::default()
        };
        let c = args.config(Role::Hub).expect("a set key");
        assert_eq!(c.get_json("transport/link/tx/lease").expect("set"), "2500");
        for bad in [
            "no-equals-sign",
            "no/such/key=1",
            "transport/link/tx/lease=\"x\"",
        ] {
            let args = ZenohArgs {
                set: vec![bad.into()],
                ..ZenohArgs::default()
            };
            let e = args.config(Role::Hub).unwrap_err().to_string();
            assert!(e.contains(&format!("--zenoh-set {bad}")), "{e}");
        }
    }
}
