//! What the benches over Zenoh share: two sessions peer to peer on loopback (the second
//! connecting to the first), a percentile of sorted samples, and the raw query they compare
//! with — a queryable answering at once on the first session, asked from the second.

use std::time::Duration;

use connector_zenoh::{Role, ZenohArgs};
use zenoh::Wait;

/// The value at fraction `p` of `sorted`.
pub(crate) fn pct(sorted: &[Duration], p: f64) -> Duration {
    sorted[((sorted.len() as f64 - 1.0) * p).round() as usize]
}

fn args(listen: &[String], connect: &[String]) -> ZenohArgs {
    ZenohArgs {
        listen: listen.to_vec(),
        connect: connect.to_vec(),
        no_multicast_scouting: true,
        root: "bench".into(),
        ..ZenohArgs::default()
    }
}

/// Two sessions on loopback: the first listens on a free port, the second connects to it.
pub(crate) async fn pair() -> (zenoh::Session, zenoh::Session) {
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("port");
    let ep = format!("tcp/127.0.0.1:{port}");
    let first = args(std::slice::from_ref(&ep), &[])
        .open(Role::Spoke)
        .await
        .expect("listening session");
    let second = args(&[], std::slice::from_ref(&ep))
        .open(Role::Spoke)
        .await
        .expect("connecting session");
    (first, second)
}

/// Declares on `answering` a queryable that answers at once: the raw query's other end.
pub(crate) async fn echo(answering: &zenoh::Session) -> zenoh::query::Queryable<()> {
    answering
        .declare_queryable("bench/raw/echo")
        .callback(|q| {
            let _ = q.reply(q.key_expr().clone(), b"{}".to_vec()).wait();
        })
        .await
        .expect("queryable")
}

/// One raw query from `asking` to the echo, with a payload the size of a small goal; whether
/// it was answered.
pub(crate) async fn raw_query(asking: &zenoh::Session) -> bool {
    let replies = asking
        .get("bench/raw/echo")
        .payload(br#"{"goal_id":"x","fields":{}}"#.to_vec())
        .consolidation(zenoh::query::ConsolidationMode::None)
        .await
        .expect("get");
    replies.recv_async().await.is_ok()
}
