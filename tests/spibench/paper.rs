//! The paper's claims that must hold, on the Fig. 1 configuration with the phantom.

use spibench::scene::experiment;
use spibench::simulation;

/// Fig. 1 with the phantom alone (the built-in file restricted to its first object).
#[test]
fn fig1_phantom_scb_matches_ideal_and_beats_imbalanced_double_arm() {
    let mut exp = experiment::load("fig1").unwrap();
    exp.objects.truncate(1);
    assert_eq!(exp.objects[0].name, "phantom");
    let out = simulation::run(&exp, &|_, _| {}).unwrap();
    let psnr = |label: &str| out.cells.iter().find(|c| c.case == label).unwrap().psnr_db;
    let scb = psnr("SCB imbalanced");
    let ideal = psnr("double-arm ideal");
    let single = psnr("single-arm complementary");
    let imbalanced = psnr("double-arm imbalanced");
    for c in &out.cells {
        eprintln!("{:<28} {:>8.2} dB  MSSIM {:.4}", c.case, c.psnr_db, c.mssim);
    }
    // Issue requirement: SCB within 0.5 dB of the ideal double arm and of the single arm, and at
    // least 10 dB above the imbalanced double arm.
    assert!(
        (scb - ideal).abs() <= 0.5,
        "SCB {scb:.2} dB vs ideal double-arm {ideal:.2} dB"
    );
    assert!(
        (scb - single).abs() <= 0.5,
        "SCB {scb:.2} dB vs single-arm {single:.2} dB"
    );
    assert!(
        scb >= imbalanced + 10.0,
        "SCB {scb:.2} dB vs imbalanced double-arm {imbalanced:.2} dB"
    );
}
