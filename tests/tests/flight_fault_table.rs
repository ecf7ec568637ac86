//! The fault-injection table end to end (`aeris bench faults`): in one default flight every
//! role is SIGKILLed and SIGSTOPped in turn (the controller holding the autopilot lease,
//! so its hot standby must take over), the reasoner emits garbage, and the camera's
//! frame service is removed under its subscriber. Each fault must be noticed and recovered
//! from, the autopilot must never receive an invalid setpoint, no decision may be lost (but
//! the one a dying hub held) and the flight must still reach its goal. Times are printed by the benchmark, not asserted.

use aeris_tests::*;
use std::process::Command;

#[test]
fn every_fault_of_the_table_is_detected_and_recovered_with_no_invalid_setpoint() {
    let dir = TempDir::new("fault-table");
    let out = Command::new(aeris_bin())
        .args(["bench", "faults", "--json", "--run-dir"])
        .arg(dir.0.join("run"))
        .output()
        .expect("run aeris bench faults");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "bench faults failed: {}\n{stdout}\n{stderr}",
        out.status
    );
    let report = last_json_line(&stdout);
    assert_eq!(report["reached_goal"], true, "{report}\n{stderr}");
    let rows = report["rows"].as_array().expect("rows");
    let roles = [
        "vehicle",
        "controller",
        "camera",
        "perception",
        "hub",
        "reasoning",
    ];
    // 6 SIGKILL + 6 SIGSTOP + garbage + service removed
    assert_eq!(rows.len(), 14, "{report}");
    for (kind, offset) in [("sigkill", 0), ("sigstop", 6)] {
        for (i, role) in roles.iter().enumerate() {
            let row = &rows[offset + i];
            assert_eq!(row["fault"], kind, "{row}");
            if *role == "controller" {
                // the controller rows hit whichever controller holds the autopilot lease
                // then: the primary or its hot standby
                assert!(
                    ["controller", "controller-standby"].contains(&row["role"].as_str().unwrap()),
                    "{row}"
                );
            } else {
                assert_eq!(row["role"], *role, "{row}");
            }
        }
    }
    assert_eq!(rows[12]["fault"], "garbage");
    assert!(
        rows[12]["rejected_decisions"].as_u64().unwrap() >= 2,
        "the hub did not reject the garbage: {}",
        rows[12]
    );
    assert_eq!(rows[13]["fault"], "service-removed");
    // the supervisor found the removed service and rebuilt it with both of its roles
    assert_eq!(rows[13]["role"], "camera+perception", "{}", rows[13]);
    for row in rows {
        assert!(
            row["detect_ms"].is_number(),
            "never detected: {row}\n{stderr}"
        );
        assert!(
            row["recover_ms"].is_number(),
            "never recovered: {row}\n{stderr}"
        );
        assert_eq!(row["invalid_setpoints"], 0, "{row}");
        // a decision waiting in the buffer of a hub that dies dies with it (the decision
        // topic keeps no history for a new hub): at most that one
        let lost_allowed = u64::from(row["role"] == "hub");
        assert!(
            row["lost_decisions"].as_u64().unwrap() <= lost_allowed,
            "decisions lost: {row}"
        );
    }
    assert!(report["role_restarts"].as_u64().unwrap() >= 14, "{report}");
}
