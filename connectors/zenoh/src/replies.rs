//! The reply handler every TRACE query uses.
//!
//! A query's replies can outlive the wait for them. A caller takes the first reply it needs,
//! or stops waiting because something else settled the question first (a ground station told
//! by the executive's withdrawal that its answer won, before the verdict itself arrives), and
//! drops the receiver; the other replies still arrive. Zenoh's channel handlers log each of
//! those as an error ("sending on a closed channel"), which an operator would read as a fault.
//! This handler hands replies to the same kind of channel (unbounded: a reply never blocks
//! Zenoh's thread) and drops the late ones with a debug line naming them.

use zenoh::query::Reply;

/// The receiving end: `recv_async` gives the replies in order, then an error once the query
/// has ended.
pub type Replies = flume::Receiver<Reply>;

/// A handler for `get(..).with(replies())`: the callback Zenoh calls, and the receiver.
pub fn replies() -> (impl Fn(Reply) + Send + Sync + 'static, Replies) {
    let (tx, rx) = flume::unbounded();
    let forward = move |reply: Reply| {
        if let Err(flume::SendError(reply)) = tx.send(reply) {
            let from = match reply.result() {
                Ok(sample) => sample.key_expr().to_string(),
                Err(e) => String::from_utf8_lossy(&e.payload().to_bytes()).into_owned(),
            };
            tracing::debug!(
                from,
                "a reply arrived after its query was no longer awaited; dropped"
            );
        }
    };
    (forward, rx)
}
