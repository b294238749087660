//! Reading a twincal `.rrd` back: which entities hold which components on which timelines, and
//! the views of the layout (blueprint) sent with it.
#![allow(dead_code)]

pub mod artifact;

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use twincal_viz::re_log_encoding::DecoderApp;
use twincal_viz::re_sdk::log::{Chunk, LogMsg};

/// What one entity holds.
#[derive(Debug, Default)]
pub struct Entity {
    /// Component identifiers, e.g. `Points3D:positions`.
    pub components: BTreeSet<String>,
    /// Timelines with data; `"static"` for static data.
    pub timelines: BTreeSet<String>,
    /// Rows per timeline (static included).
    pub rows: BTreeMap<String, usize>,
}

/// A view of the layout.
#[derive(Debug, Default, Clone)]
pub struct View {
    pub id: String,
    pub class: String,
    pub name: String,
    pub origin: String,
    pub queries: Vec<String>,
    pub has_bounds: bool,
}

#[derive(Debug, Default)]
pub struct Recording {
    pub entities: BTreeMap<String, Entity>,
    pub views: Vec<View>,
    /// The timeline the time panel opens on.
    pub timeline: Option<String>,
}

fn strings<C: twincal_viz::re_sdk_types::Component>(chunk: &Chunk, component: &'static str, text: impl Fn(&C) -> String) -> Vec<String> {
    chunk.iter_component::<C>(component.into()).flat_map(|batch| batch.iter().map(&text).collect::<Vec<_>>()).collect()
}

pub fn read(path: &Path) -> Recording {
    use twincal_viz::re_sdk::blueprint::components::{QueryExpression, TimelineName, ViewClass, ViewOrigin};
    use twincal_viz::re_sdk_types::components::Name;
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut rec = Recording::default();
    let mut views: BTreeMap<String, View> = BTreeMap::new();
    for msg in DecoderApp::decode_lazy(bytes.as_slice()) {
        let LogMsg::ArrowMsg(store, arrow) = msg.expect("decodable .rrd") else { continue };
        let chunk = Chunk::from_arrow_msg(&arrow).unwrap();
        let entity = chunk.entity_path().to_string();
        if store.is_recording() {
            let e = rec.entities.entry(entity).or_default();
            for d in chunk.component_descriptors() {
                e.components.insert(d.component.to_string());
            }
            if chunk.is_static() {
                e.timelines.insert("static".into());
                *e.rows.entry("static".into()).or_default() += chunk.num_rows();
            }
            for t in chunk.timelines().keys() {
                e.timelines.insert(t.to_string());
                *e.rows.entry(t.to_string()).or_default() += chunk.num_rows();
            }
            continue;
        }
        // Blueprint store.
        if let Some(rest) = entity.strip_prefix("/view/") {
            let mut parts = rest.splitn(2, '/');
            let id = parts.next().unwrap_or_default().to_string();
            let sub = parts.next();
            let v = views.entry(id.clone()).or_insert_with(|| View { id, ..Default::default() });
            match sub {
                None => {
                    if let Some(o) = strings::<ViewOrigin>(&chunk, "ViewBlueprint:space_origin", |o| o.0 .0.as_str().to_string()).first() {
                        v.origin = o.clone();
                    }
                    if let Some(c) = strings::<ViewClass>(&chunk, "ViewBlueprint:class_identifier", |c| c.0 .0.as_str().to_string()).first() {
                        v.class = c.clone();
                    }
                    if let Some(n) = strings::<Name>(&chunk, "ViewBlueprint:display_name", |n| n.0 .0.as_str().to_string()).first() {
                        v.name = n.clone();
                    }
                }
                Some("ViewContents") => v.queries.extend(strings::<QueryExpression>(&chunk, "ViewContents:query", |q| q.0 .0.as_str().to_string())),
                Some("VisualBounds2D") => v.has_bounds = true,
                _ => {}
            }
        } else if entity == "/time_panel" {
            rec.timeline = strings::<TimelineName>(&chunk, "TimePanelBlueprint:timeline", |t| t.0 .0.as_str().to_string()).first().cloned();
        }
    }
    rec.views = views.into_values().filter(|v| !v.class.is_empty()).collect();
    rec
}

fn under(entity: &str, prefix: &str) -> bool {
    let p = prefix.trim_end_matches("/**").trim_end_matches('/');
    p.is_empty() || entity == p || entity.starts_with(&format!("{p}/"))
}

impl Recording {
    /// The entities a view shows (its origin, or its `+`/`-` queries).
    pub fn entities_of(&self, v: &View) -> Vec<&str> {
        let resolve = |q: &str| q.trim().replace("$origin", &v.origin);
        let inc: Vec<String> = v.queries.iter().filter(|q| !q.trim().starts_with('-')).map(|q| resolve(q.trim().trim_start_matches('+').trim())).collect();
        let exc: Vec<String> = v.queries.iter().filter(|q| q.trim().starts_with('-')).map(|q| resolve(q.trim().trim_start_matches('-').trim())).collect();
        self.entities
            .keys()
            .filter(|e| if inc.is_empty() { under(e, &v.origin) } else { inc.iter().any(|p| under(e, p)) })
            .filter(|e| !exc.iter().any(|p| under(e, p)))
            .map(String::as_str)
            .collect()
    }

    /// Whether `entity` holds `component` on `timeline` (`"static"` for static data).
    pub fn holds(&self, entity: &str, component: &str, timeline: &str) -> bool {
        self.entities.get(entity).is_some_and(|e| e.components.contains(component) && e.timelines.contains(timeline))
    }

    /// Panics unless every view shows data that is visible on the time panel's timeline (static
    /// data counts everywhere): nothing opens empty.
    pub fn assert_no_empty_view(&self) {
        assert!(!self.views.is_empty(), "no layout in the recording");
        let tl = self.timeline.clone().unwrap_or_default();
        for v in &self.views {
            assert!(v.origin.starts_with('/') && v.origin.len() > 1, "view {:?} has origin {:?}", v.name, v.origin);
            let ents = self.entities_of(v);
            let visible = ents.iter().any(|e| {
                let t = &self.entities[*e].timelines;
                // The coordinate system of `/world` alone is not something to look at.
                *e != "/world" && (t.contains("static") || t.contains(&tl))
            });
            assert!(visible, "view {:?} ({}, origin {}) has no data on timeline {tl:?}: {ents:?}", v.name, v.class, v.origin);
        }
    }

    pub fn view(&self, name_part: &str) -> &View {
        self.views
            .iter()
            .find(|v| v.name.contains(name_part))
            .unwrap_or_else(|| panic!("no view named like {name_part:?} in {:?}", self.views.iter().map(|v| &v.name).collect::<Vec<_>>()))
    }
}

/// The scalar values logged at `entity`, in the order they were logged.
pub fn scalars(path: &Path, entity: &str) -> Vec<f64> {
    let bytes = std::fs::read(path).unwrap();
    let mut out = Vec::new();
    for msg in DecoderApp::decode_lazy(bytes.as_slice()) {
        let LogMsg::ArrowMsg(store, arrow) = msg.expect("decodable .rrd") else { continue };
        if !store.is_recording() {
            continue;
        }
        let chunk = Chunk::from_arrow_msg(&arrow).unwrap();
        if chunk.entity_path().to_string() == entity {
            for batch in chunk.iter_component::<twincal_viz::re_sdk_types::components::Scalar>("Scalars:scalars".into()) {
                out.extend(batch.iter().map(|s| s.0 .0));
            }
        }
    }
    out
}
