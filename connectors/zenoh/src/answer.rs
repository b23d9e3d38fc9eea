//! The ground station's side of answering a user task: one `answer` query to the executive
//! that opened the task, and its verdict.

use std::time::Duration;

use connector_api::wire::{self, Answer, AnswerReply};
use connector_api::{Channel, Keys};
use zenoh::Session;
use zenoh::query::ConsolidationMode;

use crate::codec::{encoding, json};

/// Why an answer got no verdict (a refusal is a verdict: [`AnswerReply::reason`]).
#[derive(Debug, thiserror::Error)]
pub enum AnswerError {
    /// The query could not be sent.
    #[error("zenoh: {0}")]
    Zenoh(String),
    /// No executive holds the task's mission (it ended, or the link is down).
    #[error("no executive answered within {0:?}: is the mission running and reachable?")]
    NoExecutive(Duration),
    /// The executive replied with an error or something unreadable.
    #[error("the executive's reply: {0}")]
    Reply(String),
}

/// Sends `answer` for the user task `answer.goal_id` of action `action` on `server` and
/// waits (at most `wait`) for the executive's verdict.
pub async fn send_answer(
    session: &Session,
    keys: &Keys,
    server: &str,
    action: &str,
    answer: &Answer,
    wait: Duration,
) -> Result<AnswerReply, AnswerError> {
    let key = keys.goal(server, action, Channel::Answer, &answer.goal_id);
    let replies = session
        .get(&key)
        .payload(json(answer))
        .encoding(encoding("answer"))
        .consolidation(ConsolidationMode::None)
        .timeout(wait)
        .with(crate::replies())
        .await
        .map_err(|e| AnswerError::Zenoh(e.to_string()))?;
    let reply = replies
        .recv_async()
        .await
        .map_err(|_| AnswerError::NoExecutive(wait))?;
    match reply.result() {
        Ok(sample) => {
            wire::parse::<AnswerReply>("answer reply", &key, &sample.payload().to_bytes())
                .map_err(|e| AnswerError::Reply(e.to_string()))
        }
        Err(e) => {
            let text = String::from_utf8_lossy(&e.payload().to_bytes()).into_owned();
            if text == "Timeout" {
                Err(AnswerError::NoExecutive(wait))
            } else {
                Err(AnswerError::Reply(text))
            }
        }
    }
}
