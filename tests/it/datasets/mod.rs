//! Dataset edits shared by the integration tests.

use twincal::dataset::{Dataset, Row, Split};

/// `ds` with every test row's length moved by +0.5 or −0.7 mm (alternately): a method that
/// chooses anything on the test rows would see it.
pub fn test_lengths_scrambled(ds: &Dataset) -> Dataset {
    let rows = ds
        .rows
        .iter()
        .enumerate()
        .map(|(i, r)| match r.split {
            Some(Split::Test) => Row { reading_mm: r.reading_mm.iter().map(|l| l + if i % 2 == 0 { 0.5 } else { -0.7 }).collect(), ..r.clone() },
            _ => r.clone(),
        })
        .collect();
    Dataset { rows, source: ds.source.clone() }
}
