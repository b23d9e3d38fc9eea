//! Ground stations' answers to user tasks: each `answer` query checked (an open task, the
//! form, then the engine's verdict) and answered; the first valid answer wins, and every other
//! station is told who answered.

use super::*;

impl Shared {
    /// `…/answer/<goal_id>` from a ground station: replies with the verdict.
    pub(super) async fn on_answer(self: Arc<Shared>, query: Query) {
        let reply = self.answer(&query).await;
        match &reply.reason {
            None => tracing::info!(goal_id = reply.goal_id, "answer applied"),
            Some(reason) => tracing::info!(goal_id = reply.goal_id, reason, "answer refused"),
        }
        if let Err(e) = query
            .reply(query.key_expr().clone(), json(&reply))
            .encoding(encoding("answer_reply"))
            .await
        {
            tracing::warn!(error = %e, "answer reply failed");
        }
    }

    /// Checks an answer (payload, open task, form), hands it to the executive and waits for
    /// its verdict. The first applied answer closes the task at every other station.
    pub(super) async fn answer(self: &Arc<Shared>, query: &Query) -> AnswerReply {
        let key = query.key_expr().as_str();
        let goal_id = Keys::last_chunk(key).to_owned();
        let refused = |reason: String| AnswerReply {
            goal_id: goal_id.clone(),
            applied: false,
            reason: Some(reason),
        };
        let bytes = query
            .payload()
            .map(|p| p.to_bytes().into_owned())
            .unwrap_or_default();
        let a = match wire::parse::<Answer>("answer", key, &bytes) {
            Ok(a) => a,
            Err(e) => return refused(e.to_string()),
        };
        if a.goal_id != goal_id {
            return refused(format!(
                "the answer names goal `{}` but was sent for `{goal_id}`",
                a.goal_id
            ));
        }
        if a.operator.trim().is_empty() || a.station.trim().is_empty() {
            return refused("an answer must name its operator and station".to_owned());
        }
        let operator = format!("{}@{}", a.operator, a.station);
        let _turn = self.answer_turn.lock().await;
        let action = {
            let s = self.state();
            match (s.flights.get(&goal_id), s.closed.get(&goal_id)) {
                (Some(f), _) => f.command.action.clone(),
                (None, Some(c)) if c.applied == Some((operator.clone(), a.fields.clone())) => {
                    tracing::info!(goal_id, operator, "answer repeated; it was applied");
                    return AnswerReply {
                        goal_id,
                        applied: true,
                        reason: None,
                    };
                }
                (None, Some(c)) => {
                    return refused(format!("user task `{goal_id}` is closed: {}", c.why));
                }
                // Not a task of this run: the executive judges it from what it knows (a task
                // answered before it restarted).
                (None, None) => match self.opts.keys.action_of(key) {
                    Some(action) => action.to_owned(),
                    None => return refused(format!("no open user task has goal id `{goal_id}`")),
                },
            }
        };
        if let Some(Err(e)) = self.spec(&action).map(|s| s.check_result(&a.fields)) {
            return refused(format!(
                "the answer does not fit the form of `{action}`: {e}"
            ));
        }
        let (verdict, decided) = Verdict::new();
        self.report(Report::Answer {
            goal_id: goal_id.clone(),
            fields: a.fields.clone(),
            operator: operator.clone(),
            verdict,
        });
        match decided.await {
            Ok(Ok(())) => {
                let why = format!("answered by {operator}");
                {
                    let mut s = self.state();
                    s.land(&goal_id, Ended::Reported);
                    s.closed.insert(
                        goal_id.clone(),
                        Closed {
                            why: why.clone(),
                            applied: Some((operator.clone(), a.fields)),
                        },
                    );
                }
                // Every other station drops the task, then the winner hears it won.
                Arc::clone(self)
                    .cancel(goal_id.clone(), action, Some(why))
                    .await;
                AnswerReply {
                    goal_id,
                    applied: true,
                    reason: None,
                }
            }
            Ok(Err(reason)) => refused(reason),
            Err(_) => refused("the executive is stopping; the answer was not applied".to_owned()),
        }
    }
}
