//! The services graph of a workflow: an edge from each publisher to each subscriber of a
//! topic (feedback topics, `heartbeat` and the recorder's subscriptions excepted), the cycle [`Workflow::validate`]
//! refuses, and the start order (publishers first).

use super::Workflow;
use aeris_schemas::RoleKind;
use aeris_schemas::topics;

impl Workflow {
    /// Service dependency edges `(from, to, topic)`: role `to` subscribes to `topic` that role
    /// `from` publishes. Feedback topics and `heartbeat` make no edges, nor does a topic
    /// that `to` publishes itself: peers exchanging one topic (the controllers'
    /// `controller/lease`) have no order between them. In a flight of several vehicles, a
    /// topic joins roles of the same vehicle, or a role of the whole flight and any
    /// vehicle's ([`super::RoleDecl::shares_scope_with`]).
    pub fn service_edges(&self) -> Vec<(usize, usize, String)> {
        let mut edges = Vec::new();
        for (from, a) in self.roles.iter().enumerate() {
            for topic in &a.publishes {
                if topic == topics::HEARTBEAT || self.feedback.contains(topic) {
                    continue;
                }
                for (to, b) in self.roles.iter().enumerate() {
                    // the recorder is nobody's dependant: it may start first and see the
                    // flight from its first message
                    if b.kind != RoleKind::Recorder
                        && a.shares_scope_with(b)
                        && b.subscribes.contains(topic)
                        && !b.publishes.contains(topic)
                        && !edges.iter().any(|(f, t, _)| *f == from && *t == to)
                    {
                        edges.push((from, to, topic.clone()));
                    }
                }
            }
        }
        edges
    }

    /// A cycle of the services graph as (roles with the first repeated, edge topics).
    pub(super) fn find_cycle(&self) -> Option<(Vec<String>, Vec<String>)> {
        let n = self.roles.len();
        let edges = self.service_edges();
        let mut adj: Vec<Vec<(usize, &str)>> = vec![Vec::new(); n];
        for (f, t, topic) in &edges {
            adj[*f].push((*t, topic.as_str()));
        }
        // 0 = unvisited, 1 = on the stack, 2 = done. Iterative DFS.
        let mut color = vec![0u8; n];
        for root in 0..n {
            if color[root] != 0 {
                continue;
            }
            // stack of (node, next edge index); `via[k]` is the topic into stack[k]
            let mut stack: Vec<(usize, usize)> = vec![(root, 0)];
            let mut via: Vec<&str> = vec![""];
            color[root] = 1;
            while let Some(&mut (node, ref mut next)) = stack.last_mut() {
                if let Some(&(to, topic)) = adj[node].get(*next) {
                    *next += 1;
                    match color[to] {
                        0 => {
                            color[to] = 1;
                            stack.push((to, 0));
                            via.push(topic);
                        }
                        1 => {
                            let start = stack.iter().position(|(v, _)| *v == to).unwrap_or(0);
                            let mut path: Vec<String> = stack[start..]
                                .iter()
                                .map(|(v, _)| self.roles[*v].name.clone())
                                .collect();
                            path.push(self.roles[to].name.clone());
                            let mut topics: Vec<String> =
                                via[start + 1..].iter().map(|t| t.to_string()).collect();
                            topics.push(topic.to_string());
                            return Some((path, topics));
                        }
                        _ => {}
                    }
                } else {
                    color[node] = 2;
                    stack.pop();
                    via.pop();
                }
            }
        }
        None
    }

    /// Role indices in start order: publishers before their subscribers (feedback edges
    /// ignored), ties in declaration order. On a cyclic graph (which [`Workflow::validate`]
    /// rejects) the roles left on cycles follow in declaration order.
    pub fn start_order(&self) -> Vec<usize> {
        let n = self.roles.len();
        let edges = self.service_edges();
        let mut indegree = vec![0usize; n];
        for (_, t, _) in &edges {
            indegree[*t] += 1;
        }
        let mut done = vec![false; n];
        let mut order = Vec::with_capacity(n);
        while order.len() < n {
            let next = (0..n)
                .find(|&i| !done[i] && indegree[i] == 0)
                .or_else(|| (0..n).find(|&i| !done[i]));
            let Some(i) = next else { break };
            done[i] = true;
            order.push(i);
            for (f, t, _) in &edges {
                if *f == i && !done[*t] {
                    indegree[*t] = indegree[*t].saturating_sub(1);
                }
            }
        }
        order
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::workflow::{DEFAULT_WORKFLOW_TOML, WorkflowError};

    #[test]
    fn start_order_puts_publishers_first() {
        let w = Workflow::builtin_default().unwrap();
        let order: Vec<&str> = w
            .start_order()
            .into_iter()
            .map(|i| w.roles[i].name.as_str())
            .collect();
        let pos = |n: &str| order.iter().position(|o| *o == n).unwrap();
        assert_eq!(order.len(), w.roles.len());
        assert!(pos("camera") < pos("perception"));
        assert!(pos("perception") < pos("reasoning"));
        assert!(pos("reasoning") < pos("hub"));
        assert!(pos("hub") < pos("controller"));
    }

    #[test]
    fn without_feedback_the_control_loop_is_a_cycle() {
        let text =
            DEFAULT_WORKFLOW_TOML.replace("feedback = [\"vehicle/telemetry\"]", "feedback = []");
        assert_ne!(text, DEFAULT_WORKFLOW_TOML, "default.toml lists feedback");
        match Workflow::from_toml_str(&text) {
            Err(WorkflowError::Cycle { path, topics }) => {
                assert_eq!(path.first(), path.last());
                assert_eq!(topics.len() + 1, path.len());
                assert!(topics.contains(&topics::VEHICLE_TELEMETRY.to_string()));
                assert!(path.contains(&"controller".to_string()));
            }
            other => panic!("expected a cycle, got {other:?}"),
        }
    }
}
