//! `twincal plan`: the library's [`twincal::jobs::PlanJob`], and what it prints.

use super::*;

/// Plans, writes, and prints the plan's summary.
pub fn plan(job: &twincal::jobs::PlanJob, quiet: bool) -> Result<()> {
    let p = job.run(&twincal_viz::Rerun)?;
    // Every warning is a `warning:` line on stderr, also with --quiet.
    if p.ceiling.is_none() {
        eprintln!("warning: no ceiling: {}", p.ceiling_note.as_deref().unwrap_or("none computed"));
    }
    p.warnings.iter().for_each(|w| eprintln!("warning: {w}"));
    if quiet {
        return Ok(());
    }
    let c = &p.candidates;
    let refused: Vec<String> = c.refused.iter().map(|(k, v)| format!("{k} {v}")).collect();
    eprintln!(
        "planned {} poses of {} feasible candidates ({} drawn{}) in {:.2} s",
        p.poses.len(),
        c.q.len(),
        c.drawn,
        if refused.is_empty() { String::new() } else { format!("; refused: {}", refused.join(", ")) },
        p.seconds
    );
    eprintln!(
        "  {} parameters of the {} model identifiable ({} held: no candidate tells them apart); criterion {}: {}",
        p.identifiable.len(),
        p.parametrisation,
        p.fixed.len(),
        p.criterion,
        p.criterion_describe
    );
    if let Some(features) = &p.features {
        let mut counts: Vec<(&str, usize)> = Vec::new();
        for f in features {
            match counts.iter_mut().find(|(v, _)| v == f) {
                Some((_, k)) => *k += 1,
                None => counts.push((f, 1)),
            }
        }
        let list: Vec<String> = counts.iter().map(|(f, k)| format!("{f} {k}")).collect();
        eprintln!("  configurations per placement and feature, in the tour's order: {}", list.join(", "));
    }
    if let Some(payloads) = &p.payload_kg {
        let mut counts: Vec<(f64, usize)> = Vec::new();
        for m in payloads {
            match counts.iter_mut().find(|(v, _)| v == m) {
                Some((_, k)) => *k += 1,
                None => counts.push((*m, 1)),
            }
        }
        let text: Vec<String> = counts.iter().map(|(m, k)| format!("{m} kg × {k}")).collect();
        eprintln!("  payloads: {} (measured one payload after the other)", text.join(", "));
    }
    eprintln!("  index                                     plan    random sets of {} (median of {})", p.poses.len(), twincal::plan::RANDOM_SETS);
    let (a, b) = (&p.indices, &p.random_median);
    for (name, x, y) in [
        ("mean prediction variance (I, lower better)", a.i_prediction_variance, b.i_prediction_variance),
        ("O1 (D-optimal)", a.o1_d, b.o1_d),
        ("O3 (smallest singular value)", a.o3_min_sv, b.o3_min_sv),
        ("O4 (noise amplification)", a.o4_noise, b.o4_noise),
        ("O5", a.o5_a, b.o5_a),
        ("condition number", a.condition, b.condition),
    ] {
        eprintln!("  {name:<42} {:<8} {}", shown(x), shown(y));
    }
    if let Some(ce) = &p.ceiling {
        let worth = |w: Option<usize>| w.map_or(format!("more than {}", ce.searched_to), |k| format!("about {k}"));
        eprintln!(
            "  best any {n} poses of this pool can do: I >= {} (a certified bound, {} iterations); the plan is {:.0} % above it",
            shown(ce.bound.lower),
            ce.bound.iterations,
            100.0 * (a.i_prediction_variance / ce.bound.lower - 1.0),
            n = p.poses.len()
        );
        eprintln!(
            "  worth in random feasible poses (estimated, median I of 25 draws): the plan {}, the best possible {n} {}",
            worth(ce.plan_worth),
            worth(ce.best_worth),
            n = p.poses.len()
        );
    }
    eprintln!(
        "  tour: {:.0} s ({:.0} s moving, {:.0} s holding and reading{}); in the design's order {:.0} s",
        p.tour.total_s,
        p.tour.moving_s,
        p.tour.reading_s,
        if p.tour.payload_changes_s > 0.0 { format!(", {:.0} s changing the payload", p.tour.payload_changes_s) } else { String::new() },
        p.unordered.total_s
    );
    eprintln!("  wrote {}/{} and {}/{}", job.out.display(), twincal::jobs::POSES_FILE, job.out.display(), twincal::jobs::PLAN_FILE);
    if let Some(lang) = job.program_format {
        let files: Vec<String> = lang.file_names(twincal::jobs::PROGRAM_NAME).iter().map(|n| job.out.join(n).display().to_string()).collect();
        eprintln!("  wrote the measurement program ({}): {}", lang.name(), files.join(" and "));
    }
    if let Some(r) = &job.rrd {
        eprintln!("  wrote {}", r.display());
    }
    Ok(())
}

fn shown(v: f64) -> String {
    if v.is_finite() && v != 0.0 && (v.abs() < 1e-3 || v.abs() >= 1e4) {
        format!("{v:.3e}")
    } else {
        format!("{v:.4}")
    }
}
