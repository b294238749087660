use super::*;

fn tour(joints: usize) -> Tour {
    let q = (0..5).map(|i| (0..joints).map(|j| ((i * 7 + j * 3) as f64 * 0.37).sin() * 2.0).collect()).collect();
    Tour {
        name: "twincal_plan".into(),
        q,
        payload_kg: Some(vec![0.0, 0.0, 2.5, 2.5, 0.0]),
        hold_s: 2.0,
        speed_fraction: 0.2,
        about: vec!["planned by a test".into()],
    }
}

/// Every language's program moves to the tour's poses in order (read back to a micro-degree),
/// measures after each move, and stops for each payload change only.
#[test]
fn a_measurement_program_moves_through_the_tour_and_waits_at_each_pose() {
    for lang in Language::ALL {
        for joints in lang.dialect().joints() {
            let t = tour(joints);
            let files = lang.measurement_program(&t).unwrap();
            let back = lang.joint_targets(&files).unwrap();
            assert_eq!(back.len(), t.q.len(), "{}", lang.name());
            for (a, b) in back.iter().zip(&t.q) {
                assert_eq!(a.len(), b.len(), "{} {joints}", lang.name());
                assert!(a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-6f64.to_radians()), "{}: {a:?} vs {b:?}", lang.name());
            }
            let text: String = files.iter().map(|f| f.text.as_str()).collect();
            let lower = text.to_ascii_lowercase();
            // One wait per pose, after its move; the payload changes (first pose, third, fifth).
            assert_eq!(lower.matches("twc_measure(").count() + lower.matches("twc_measure ").count() - 1, t.q.len(), "{}: {text}", lang.name());
            assert_eq!(text.matches("kg payload").count(), 3, "{}", lang.name());
            assert!(text.contains("planned by a test"));
        }
    }
}

#[test]
fn tours_no_controller_runs_are_refused() {
    let bad = |t: Tour, lang: Language| lang.measurement_program(&t).unwrap_err().to_string();
    assert!(bad(Tour { name: "9lives".into(), ..tour(6) }, Language::Rapid).contains("program name"));
    for (name, lang) in [("MODULE", Language::Rapid), ("def", Language::Krl), ("Thread", Language::Urscript), ("ptp", Language::Rapid)] {
        assert!(bad(Tour { name: name.into(), ..tour(6) }, lang).contains("is a keyword"), "{name}");
    }
    assert!(bad(Tour { q: vec![], ..tour(6) }, Language::Krl).contains("at least one pose"));
    let mut nan = tour(6);
    nan.q[2][1] = f64::NAN;
    assert!(bad(nan, Language::Urscript).contains("pose 3"));
    assert!(bad(tour(7), Language::Urscript).contains("6 to 6 joints"));
    assert!(bad(Tour { hold_s: -1.0, ..tour(6) }, Language::Rapid).contains("--hold-s"));
}

/// The RAPID module is one module with its declarations before its routines, and a tour
/// without payloads never stops.
#[test]
fn a_rapid_module_is_whole() {
    let t = Tour { payload_kg: None, ..tour(6) };
    let text = &Language::Rapid.measurement_program(&t).unwrap()[0].text;
    assert!(text.starts_with("MODULE twincal_plan\n") && text.ends_with("ENDMODULE\n"), "{text}");
    assert!(!text.contains("Stop;"));
    assert!(text.find("CONST jointtarget twc_p5").unwrap() < text.find("PROC main()").unwrap());
    assert_eq!(text.matches("PROC ").count(), text.matches("ENDPROC").count());
}
