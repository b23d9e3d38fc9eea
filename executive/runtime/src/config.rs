//! The executive's configuration: built-in defaults, then a TOML file, then `TRACE_*`
//! environment variables, then command-line flags — each later source overriding the earlier.
//! Unknown keys and bad values are refused at start, naming the key and where it came from.

use std::path::{Path, PathBuf};

use serde::Deserialize;

/// The configuration file's shape (`deploy/executive.toml`). Every key is optional.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct File {
    /// `[store]`
    #[serde(default)]
    pub store: StoreSection,
    /// `[record]`
    #[serde(default)]
    pub record: RecordSection,
    /// `[clock]`
    #[serde(default)]
    pub clock: ClockSection,
    /// `[connector]`
    #[serde(default)]
    pub connector: ConnectorSection,
    /// `[log]`
    #[serde(default)]
    pub log: LogSection,
    /// `[zenoh]`
    #[serde(default)]
    pub zenoh: ZenohSection,
}

/// `[zenoh]`: which deployment the executive joins.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ZenohSection {
    /// The deployment name (one key chunk; every key is `<key-root>/<deployment>/…`).
    pub deployment: Option<String>,
}

/// `[store]`: where and how often the executive persists.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StoreSection {
    /// Store directory.
    pub dir: Option<PathBuf>,
    /// Steps between snapshots.
    pub snapshot_every: Option<u64>,
}

/// `[record]`: the execution record.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecordSection {
    /// Record file.
    pub path: Option<PathBuf>,
}

/// `[clock]`: mission time.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClockSection {
    /// Mission time runs this many times faster than wall time.
    pub speed: Option<f64>,
}

/// `[connector]`: the connectors.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConnectorSection {
    /// The scripted connector's script file.
    pub script: Option<PathBuf>,
    /// The connector configuration (`deploy/connectors.toml`).
    pub config: Option<PathBuf>,
}

/// `[log]`: logging.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LogSection {
    /// An env-filter directive, e.g. `info,executive=debug`.
    pub filter: Option<String>,
    /// `text` or `json`.
    pub format: Option<String>,
}

/// The resolved settings.
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    /// Store directory (`None`: beside the mission).
    pub store: Option<PathBuf>,
    /// Steps between snapshots.
    pub snapshot_every: u64,
    /// Record file (`None`: in the store).
    pub record: Option<PathBuf>,
    /// Clock speed.
    pub speed: f64,
    /// Connector script.
    pub script: Option<PathBuf>,
    /// Connector configuration.
    pub connectors: Option<PathBuf>,
    /// Log filter.
    pub log_filter: String,
    /// Log lines as JSON.
    pub log_json: bool,
    /// The deployment (`None`: the `--deployment` flag or the built-in `default`).
    pub deployment: Option<String>,
}

impl Default for Settings {
    fn default() -> Settings {
        Settings {
            store: None,
            snapshot_every: 1000,
            record: None,
            speed: 1.0,
            script: None,
            connectors: None,
            log_filter: "warn".to_owned(),
            log_json: false,
            deployment: None,
        }
    }
}

/// A refused configuration.
#[derive(Debug, thiserror::Error)]
#[error("configuration: {0}")]
pub struct ConfigError(pub String);

impl Settings {
    /// Applies a configuration file.
    pub fn with_file(self, path: &Path) -> Result<Settings, ConfigError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| ConfigError(format!("{}: {e}", path.display())))?;
        self.with_text(&text, &path.display().to_string())
    }

    /// Applies a configuration file's text; `from` names it in errors.
    pub fn with_text(mut self, text: &str, from: &str) -> Result<Settings, ConfigError> {
        let f: File = toml::from_str(text).map_err(|e| ConfigError(format!("{from}: {e}")))?;
        self.store = f.store.dir.or(self.store);
        if let Some(n) = f.store.snapshot_every {
            self.snapshot_every = positive_int("store.snapshot_every", n, from)?;
        }
        self.record = f.record.path.or(self.record);
        if let Some(s) = f.clock.speed {
            self.speed = positive("clock.speed", s, from)?;
        }
        self.script = f.connector.script.or(self.script);
        self.connectors = f.connector.config.or(self.connectors);
        self.log_filter = f.log.filter.unwrap_or(self.log_filter);
        if let Some(fmt) = f.log.format {
            self.log_json = format_is_json(&fmt, from)?;
        }
        if let Some(d) = f.zenoh.deployment {
            self.deployment = Some(deployment("zenoh.deployment", d, from)?);
        }
        Ok(self)
    }

    /// Applies `TRACE_*` environment variables read through `get`.
    pub fn with_env(
        mut self,
        get: &dyn Fn(&str) -> Option<String>,
    ) -> Result<Settings, ConfigError> {
        let parse = |key: &str, v: &str| -> Result<f64, ConfigError> {
            v.trim()
                .parse::<f64>()
                .map_err(|_| ConfigError(format!("{key}=`{v}` (environment) is not a number")))
        };
        if let Some(v) = get("TRACE_STORE") {
            self.store = Some(PathBuf::from(v));
        }
        if let Some(v) = get("TRACE_SNAPSHOT_EVERY") {
            let n = v.trim().parse::<u64>().map_err(|_| {
                ConfigError(format!(
                    "TRACE_SNAPSHOT_EVERY=`{v}` (environment) is not a whole number"
                ))
            })?;
            self.snapshot_every = positive_int("TRACE_SNAPSHOT_EVERY", n, "environment")?;
        }
        if let Some(v) = get("TRACE_RECORD") {
            self.record = Some(PathBuf::from(v));
        }
        if let Some(v) = get("TRACE_SPEED") {
            self.speed = positive("TRACE_SPEED", parse("TRACE_SPEED", &v)?, "environment")?;
        }
        if let Some(v) = get("TRACE_SCRIPT") {
            self.script = Some(PathBuf::from(v));
        }
        if let Some(v) = get("TRACE_CONNECTORS") {
            self.connectors = Some(PathBuf::from(v));
        }
        if let Some(v) = get("TRACE_LOG") {
            self.log_filter = v;
        }
        if let Some(v) = get("TRACE_LOG_FORMAT") {
            self.log_json = format_is_json(&v, "environment")?;
        }
        if let Some(v) = get("TRACE_DEPLOYMENT") {
            self.deployment = Some(deployment("TRACE_DEPLOYMENT", v, "environment")?);
        }
        Ok(self)
    }

    /// The Zenoh flags with the configured deployment where `--deployment` was not given
    /// (the flag wins over the environment, which wins over the file).
    pub fn zenoh(&self, mut args: connector_zenoh::ZenohArgs) -> connector_zenoh::ZenohArgs {
        if args.deployment.is_none() {
            args.deployment.clone_from(&self.deployment);
        }
        args
    }
}

fn deployment(key: &str, v: String, from: &str) -> Result<String, ConfigError> {
    connector_api::keys::check_chunk(&v)
        .map(|()| v)
        .map_err(|e| ConfigError(format!("{key} ({from}): deployment {e}")))
}

fn positive(key: &str, v: f64, from: &str) -> Result<f64, ConfigError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(ConfigError(format!(
            "{key} = {v} ({from}) must be a positive number"
        )))
    }
}

fn positive_int(key: &str, v: u64, from: &str) -> Result<u64, ConfigError> {
    if v > 0 {
        Ok(v)
    } else {
        Err(ConfigError(format!(
            "{key} = 0 ({from}) must be at least 1"
        )))
    }
}

fn format_is_json(v: &str, from: &str) -> Result<bool, ConfigError> {
    match v.trim() {
        "json" => Ok(true),
        "text" => Ok(false),
        other => Err(ConfigError(format!(
            "log format `{other}` ({from}) must be `text` or `json`"
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file(text: &str) -> PathBuf {
        static N: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
        let n = N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let p = std::env::temp_dir().join(format!("trace-config-{}-{n}.toml", std::process::id()));
        std::fs::write(&p, text).expect("write");
        p
    }

    #[test]
    fn later_sources_override_earlier_ones() {
        let p = file("[clock]\nspeed = 20.0\n[store]\nsnapshot_every = 50\n");
        let s = Settings::default().with_file(&p).expect("valid");
        assert_eq!((s.speed, s.snapshot_every), (20.0, 50));
        let env = |k: &str| (k == "TRACE_SPEED").then(|| "60".to_owned());
        let s = s.with_env(&env).expect("valid");
        assert_eq!((s.speed, s.snapshot_every), (60.0, 50));
    }

    #[test]
    fn unknown_keys_and_bad_values_are_refused_by_name() {
        let e = Settings::default()
            .with_file(&file("[clock]\nspede = 2.0\n"))
            .expect_err("refused");
        assert!(e.to_string().contains("spede"), "{e}");
        let e = Settings::default()
            .with_file(&file("[clock]\nspeed = -1.0\n"))
            .expect_err("refused");
        assert!(e.to_string().contains("clock.speed"), "{e}");
        let e = Settings::default()
            .with_file(&file("[log]\nformat = \"xml\"\n"))
            .expect_err("refused");
        assert!(e.to_string().contains("xml"), "{e}");
        let env = |k: &str| (k == "TRACE_SPEED").then(|| "fast".to_owned());
        let e = Settings::default().with_env(&env).expect_err("refused");
        assert!(e.to_string().contains("TRACE_SPEED"), "{e}");
        let e = Settings::default()
            .with_file(&file("[zenoh]\ndeployment = \"a/b\"\n"))
            .expect_err("refused");
        assert!(e.to_string().contains("zenoh.deployment"), "{e}");
    }

    #[test]
    fn the_deployment_comes_from_the_flag_the_environment_or_the_file() {
        let s = Settings::default()
            .with_file(&file("[zenoh]\ndeployment = \"site-1\"\n"))
            .expect("valid");
        let flags = connector_zenoh::ZenohArgs::default();
        assert_eq!(s.zenoh(flags.clone()).deployment.as_deref(), Some("site-1"));
        let env = |k: &str| (k == "TRACE_DEPLOYMENT").then(|| "site-2".to_owned());
        let s = s.with_env(&env).expect("valid");
        assert_eq!(s.zenoh(flags).deployment.as_deref(), Some("site-2"));
        let flag = connector_zenoh::ZenohArgs {
            deployment: Some("site-3".into()),
            ..Default::default()
        };
        assert_eq!(s.zenoh(flag).deployment.as_deref(), Some("site-3"));
    }
}
