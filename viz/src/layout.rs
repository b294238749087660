//! The viewer layout (Rerun "blueprint") of a recording, as plain data: containers of views,
//! which timeline the time panel opens on. [`super::Recorder::layout`] sends it; views whose
//! entities got no data are pruned first ([`Layout::prune`]), so no panel opens empty.

use std::collections::BTreeSet;

/// What a view draws.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ViewKind {
    /// 3-D scene (points, lines, transforms), mm.
    Spatial3d,
    /// 2-D scene; twincal draws its scatter plots in it (see [`super::plot`]).
    Spatial2d,
    /// Scalars against the selected timeline.
    TimeSeries,
    /// Bar charts and histograms.
    BarChart,
    /// Markdown documents.
    Text,
    /// Text log entries.
    TextLog,
}

/// One view: its kind, title, origin entity and optional content queries (Rerun query syntax,
/// `+ /a/**`, `- /a/b/**`; empty = everything under the origin).
#[derive(Clone, Debug, PartialEq)]
pub struct ViewSpec {
    pub kind: ViewKind,
    pub name: String,
    pub origin: String,
    pub contents: Vec<String>,
    /// 2-D views: the visible rectangle `[x_min, x_max, y_min, y_max]` (else fitted by the viewer).
    pub bounds: Option<[f64; 4]>,
}

/// A tree of containers with views as leaves.
#[derive(Clone, Debug, PartialEq)]
pub enum Layout {
    View(ViewSpec),
    /// Side by side, with relative column widths (empty: equal).
    Horizontal(Vec<Layout>, Vec<f32>),
    /// Stacked, with relative row heights (empty: equal).
    Vertical(Vec<Layout>, Vec<f32>),
    /// A grid with this many columns.
    Grid(Vec<Layout>, u32),
    Tabs(Vec<Layout>),
}

/// A layout with the time panel's starting state.
#[derive(Clone, Debug, PartialEq)]
pub struct Blueprint {
    pub root: Layout,
    /// The timeline selected when the recording opens.
    pub timeline: Option<String>,
    /// Open with the time cursor at the end of the timeline (rather than playing from the start).
    pub at_end: bool,
}

impl Layout {
    /// A view of `kind` titled `name` showing everything under `origin`.
    pub fn view(kind: ViewKind, name: &str, origin: &str) -> Layout {
        Layout::View(ViewSpec { kind, name: name.into(), origin: origin.into(), contents: Vec::new(), bounds: None })
    }

    /// A 2-D view framing a [`super::plot::Plot`] logged under `origin`.
    pub fn plot(name: &str, origin: &str) -> Layout {
        Layout::View(ViewSpec { kind: ViewKind::Spatial2d, name: name.into(), origin: origin.into(), contents: Vec::new(), bounds: Some(super::plot::BOUNDS) })
    }

    /// A view with explicit content queries (`+ /world/**`, `- /world/after/**`).
    pub fn view_of(kind: ViewKind, name: &str, origin: &str, contents: &[&str]) -> Layout {
        Layout::View(ViewSpec { kind, name: name.into(), origin: origin.into(), contents: contents.iter().map(|s| s.to_string()).collect(), bounds: None })
    }

    /// Every view in the tree.
    pub fn views(&self) -> Vec<&ViewSpec> {
        match self {
            Layout::View(v) => vec![v],
            Layout::Horizontal(c, _) | Layout::Vertical(c, _) | Layout::Grid(c, _) | Layout::Tabs(c) => c.iter().flat_map(|l| l.views()).collect(),
        }
    }

    /// The layout without views that would show nothing: a view is kept when some entity in
    /// `logged` (paths with a leading `/`) lies under its origin (or its `+ …` queries) and is
    /// not excluded by its `- …` queries. Containers left empty go too, and their size shares
    /// with them. `None` if nothing is left.
    pub fn prune(&self, logged: &BTreeSet<String>) -> Option<Layout> {
        match self {
            Layout::View(v) => v.has_data(logged).then(|| self.clone()),
            Layout::Horizontal(c, s) => prune_children(c, s, logged).map(|(c, s)| Layout::Horizontal(c, s)),
            Layout::Vertical(c, s) => prune_children(c, s, logged).map(|(c, s)| Layout::Vertical(c, s)),
            Layout::Grid(c, n) => prune_children(c, &[], logged).map(|(c, _)| {
                let cols = (*n).min(c.len() as u32).max(1);
                Layout::Grid(c, cols)
            }),
            Layout::Tabs(c) => prune_children(c, &[], logged).map(|(c, _)| Layout::Tabs(c)),
        }
    }
}

fn prune_children(children: &[Layout], shares: &[f32], logged: &BTreeSet<String>) -> Option<(Vec<Layout>, Vec<f32>)> {
    let mut kept = Vec::new();
    let mut kept_shares = Vec::new();
    for (i, c) in children.iter().enumerate() {
        if let Some(p) = c.prune(logged) {
            kept.push(p);
            if let Some(s) = shares.get(i) {
                kept_shares.push(*s);
            }
        }
    }
    if kept_shares.len() != kept.len() {
        kept_shares.clear();
    }
    (!kept.is_empty()).then_some((kept, kept_shares))
}

/// `/a/b` for `a/b`, `/a/b/`, `/a/b/**`.
fn normalise(path: &str) -> String {
    let p = path.trim().trim_end_matches("**").trim_end_matches('/');
    if p.starts_with('/') {
        p.to_string()
    } else {
        format!("/{p}")
    }
}

fn under(entity: &str, prefix: &str) -> bool {
    prefix == "/" || entity == prefix || entity.starts_with(&format!("{prefix}/"))
}

impl ViewSpec {
    /// Whether some logged entity falls in this view.
    pub fn has_data(&self, logged: &BTreeSet<String>) -> bool {
        let origin = normalise(&self.origin);
        let includes: Vec<String> =
            self.contents.iter().filter(|q| !q.trim_start().starts_with('-')).map(|q| normalise(q.trim_start().trim_start_matches('+'))).collect();
        let excludes: Vec<String> =
            self.contents.iter().filter(|q| q.trim_start().starts_with('-')).map(|q| normalise(q.trim_start().trim_start_matches('-'))).collect();
        logged.iter().any(|e| {
            let included = if includes.is_empty() { under(e, &origin) } else { includes.iter().any(|p| under(e, p)) };
            included && !excludes.iter().any(|p| under(e, p))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn views_without_data_are_pruned_with_their_shares() {
        let logged: BTreeSet<String> = ["/world/arm", "/world/before/points", "/plots/q1/points"].iter().map(|s| s.to_string()).collect();
        let l = Layout::Horizontal(
            vec![
                Layout::view_of(ViewKind::Spatial3d, "before", "/world", &["+ /world/**", "- /world/after/**"]),
                Layout::view_of(ViewKind::Spatial3d, "after only", "/world", &["+ /world/after/**"]),
                Layout::Grid(vec![Layout::view(ViewKind::Spatial2d, "q1", "/plots/q1"), Layout::view(ViewKind::Spatial2d, "q2", "/plots/q2")], 3),
                Layout::Tabs(vec![Layout::view(ViewKind::TimeSeries, "empty", "/series")]),
            ],
            vec![2.0, 1.0, 3.0, 1.0],
        );
        let p = l.prune(&logged).unwrap();
        let names: Vec<&str> = p.views().iter().map(|v| v.name.as_str()).collect();
        assert_eq!(names, ["before", "q1"]);
        match &p {
            Layout::Horizontal(c, s) => {
                assert_eq!(s, &vec![2.0, 3.0]);
                assert_eq!(c[1], Layout::Grid(vec![Layout::view(ViewKind::Spatial2d, "q1", "/plots/q1")], 1));
            }
            other => panic!("{other:?}"),
        }
        assert!(Layout::view(ViewKind::Text, "x", "/docs").prune(&logged).is_none());
        // The root origin matches everything; a prefix does not match a longer name.
        assert!(Layout::view(ViewKind::Text, "x", "/").prune(&logged).is_some());
        assert!(Layout::view(ViewKind::Text, "x", "/plots/q").prune(&logged).is_none());
    }
}
