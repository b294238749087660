//! Hide one non-geometric effect in the IRB 120's geometric scenario (drawn from a seed, at a
//! size a rigid calibration cannot absorb), generate the data, and let the diagnosis find it:
//! what was hidden, what the diagnosis names, its size with its uncertainty, and the held-out
//! error it removes.
//!
//! `cargo run --release --example find_hidden_effect [SEED]` (CI runs it with the default seed).

use twincal::diagnose::hidden::hidden;
use twincal::diagnose::{diagnose, DiagnoseOptions};
use twincal::requests::DiagnoseRequest;
use twincal::sim::generate::{generate, Silent};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let seed: u64 = match std::env::args().nth(1) {
        Some(s) => s.parse().map_err(|e| format!("SEED {s:?}: {e}"))?,
        None => 4,
    };
    // The generator knows what it hid; the diagnosis below sees only the dataset.
    let (scenario, robot, hid) = hidden(seed, 1)?;
    let generated = generate(&scenario, &robot, &Silent)?;
    for h in &hid {
        println!(
            "hidden: {} on joint {} of size {:.4} ({:.1}x the noise after a rigid fit)",
            h.cause.name(),
            h.joint.map_or(0, |j| j + 1),
            h.magnitude,
            h.factor
        );
    }

    // What `twincal diagnose --data DIR` asks for, with its checks.
    let (options, _limit): (DiagnoseOptions, _) = DiagnoseRequest::default().options()?;
    let (diagnosis, _model) = diagnose(&generated.dataset, &options, &|line| eprintln!("  {line}"))?;
    println!("verdict: {}", diagnosis.verdict);
    for c in &diagnosis.causes {
        println!(
            "named: {} on joint {} of size {:.4} ± {:.4} {}; held-out RMSE {:.4} -> {:.4} mm",
            c.cause,
            c.joint.unwrap_or(0),
            c.magnitude,
            c.uncertainty,
            c.unit,
            c.heldout_rmse_before_mm,
            c.heldout_rmse_after_mm
        );
    }
    let found = hid.iter().all(|h| diagnosis.causes.iter().any(|c| h.named_by(c) && h.sized_by(c)));
    if !found {
        return Err("the diagnosis did not name the hidden effect at its size".into());
    }
    Ok(())
}
