//! The C header `include/uavloc/messages.h` against the Rust wire types: a C program built from the header
//! (with the system C compiler, `cc` or `$CC`) prints every struct's size and alignment, every field's
//! offset, the version macros and the type-name macros; each must equal the Rust value. A C or C++ front
//! end built on the header then reads and writes exactly the bytes the Rust processes do.

use std::collections::BTreeMap;
use std::mem::{align_of, offset_of, size_of};
use std::process::Command;

use protocol::{
    Command as Cmd, Control, Estimate, Header, HeldBurst, HeldBursts, Measurement, Message, Name16, Stamps, StateEcho,
    SwarmState, TrackWindow, Truth, WindowBurst,
};

/// One struct: its C name, Rust size and alignment, and (field, Rust offset) pairs.
struct Layout {
    c_name: &'static str,
    size: usize,
    align: usize,
    fields: Vec<(&'static str, usize)>,
}

macro_rules! layout {
    ($t:ty, $c:literal, [$($f:ident),* $(,)?]) => {
        Layout {
            c_name: $c,
            size: size_of::<$t>(),
            align: align_of::<$t>(),
            fields: vec![$((stringify!($f), offset_of!($t, $f))),*],
        }
    };
}

fn layouts() -> Vec<Layout> {
    vec![
        layout!(
            Stamps,
            "uavloc_stamps",
            [
                published_ns,
                trigger_command_published_ns,
                trigger_command_received_ns,
                measurement_published_ns,
                measurement_received_ns,
                estimate_published_ns,
                estimate_received_ns,
                command_published_ns,
            ]
        ),
        layout!(Header, "uavloc_header", [version, run, step, seq, stamps]),
        layout!(Name16, "uavloc_name16", [bytes]),
        layout!(
            Measurement,
            "uavloc_measurement",
            [
                header,
                count,
                heard,
                flags,
                reserved,
                uavs,
                arrivals,
                sigmas,
                headings,
                position_sigmas,
                position_bias_sigmas,
                clock_sigmas_ns,
                clock_bias_sigmas_ns,
            ]
        ),
        layout!(
            Estimate,
            "uavloc_estimate",
            [
                header,
                instance,
                count,
                status,
                estimator,
                model,
                rejected_run,
                heard,
                outliers,
                confirmed,
                alternative,
                drop_uavs,
                drop_run,
                reserved,
                position,
                covariance,
                uavs,
                headings,
                velocity,
                cross_cov,
                velocity_cov,
                sigmas,
                bias_cov,
                bias_sensitivity,
                alt_mean,
                alt_cov,
                alt_bias_sensitivity,
                held,
                window,
            ]
        ),
        layout!(
            HeldBurst,
            "uavloc_held_burst",
            [step, count, uavs, reserved, positions, arrival_diff, sigmas, bias_sigmas]
        ),
        layout!(HeldBursts, "uavloc_held_bursts", [count, reserved, bursts]),
        layout!(
            WindowBurst,
            "uavloc_window_burst",
            [step, count, heard, reserved, positions, arrivals, sigmas, bias_sigmas]
        ),
        layout!(TrackWindow, "uavloc_track_window", [open, count, reserved, base_matrix, base_vector, bursts]),
        layout!(
            Cmd,
            "uavloc_command",
            [
                header,
                planner_instance,
                plan_time_us,
                active_constraints,
                violated_constraints,
                count,
                flags,
                objective,
                headings,
                waypoints,
                solver,
                objective_name,
                state,
            ]
        ),
        layout!(
            StateEcho,
            "uavloc_state_echo",
            [
                step,
                kind,
                estimator,
                model,
                rejected_run,
                confirmed,
                alternative,
                drop_uavs,
                drop_run,
                position,
                covariance,
                velocity,
                cross_cov,
                velocity_cov,
                bias_sensitivity,
                alt_mean,
                alt_cov,
                alt_bias_sensitivity,
                held,
                window
            ]
        ),
        layout!(Truth, "uavloc_truth", [header, position, previous_command, multipath]),
        layout!(
            SwarmState,
            "uavloc_swarm_state",
            [header, count, reserved, positions, lat_lon_deg, altitude_m, headings, velocities, fix_ns, link, rejected]
        ),
        layout!(Control, "uavloc_control", [header, instance, started_ns, kind, reserved, run, role, detail]),
    ]
}

/// The C program that prints what the header says, one `key value` line each.
fn c_source(layouts: &[Layout]) -> String {
    let mut src = String::from(
        "#include <stdio.h>\n#include <stddef.h>\n#include <stdalign.h>\n#include \"uavloc/messages.h\"\nint main(void) {\n",
    );
    for l in layouts {
        let c = l.c_name;
        src += &format!("  printf(\"{c}.size %zu\\n\", sizeof({c}));\n");
        src += &format!("  printf(\"{c}.align %zu\\n\", alignof({c}));\n");
        for (f, _) in &l.fields {
            src += &format!("  printf(\"{c}.{f} %zu\\n\", offsetof({c}, {f}));\n");
        }
    }
    for m in ["MEASUREMENT", "ESTIMATE", "COMMAND", "TRUTH", "CONTROL", "SWARM"] {
        src += &format!("  printf(\"version.{m} %u\\n\", UAVLOC_{m}_VERSION);\n");
        src += &format!("  printf(\"type_name.{m} %s\\n\", UAVLOC_TYPE_NAME_{m});\n");
    }
    src += "  printf(\"max_uavs %d\\n\", UAVLOC_MAX_UAVS);\n";
    src += "  printf(\"flag_hold %u\\n\", UAVLOC_COMMAND_FLAG_HOLD);\n";
    src += "  printf(\"in_flight %llu\\n\", (unsigned long long)UAVLOC_CONTROL_IN_FLIGHT);\n";
    src += "  return 0;\n}\n";
    src
}

#[test]
fn the_c_header_has_the_layout_of_the_rust_types() {
    let _scenario = crate::common::scenario(module_path!());
    let layouts = layouts();
    let dir = std::env::temp_dir().join(format!("uavloc-wire-layout-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (source, exe) = (dir.join("layout.c"), dir.join("layout"));
    std::fs::write(&source, c_source(&layouts)).unwrap();
    let include = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("include");
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    let built = Command::new(&cc)
        .args(["-std=c11", "-Wall", "-Werror", "-I"])
        .arg(&include)
        .arg(&source)
        .arg("-o")
        .arg(&exe)
        .output()
        .unwrap_or_else(|e| panic!("running the C compiler {cc:?}: {e}"));
    assert!(built.status.success(), "the header does not compile: {}", String::from_utf8_lossy(&built.stderr));
    let out = Command::new(&exe).output().unwrap();
    let text = String::from_utf8(out.stdout).unwrap();
    let c: BTreeMap<&str, &str> = text.lines().filter_map(|l| l.split_once(' ')).collect();
    let get = |key: &str| *c.get(key).unwrap_or_else(|| panic!("{key} missing from the C output:\n{text}"));
    for l in &layouts {
        assert_eq!(get(&format!("{}.size", l.c_name)), l.size.to_string(), "size of {}", l.c_name);
        assert_eq!(get(&format!("{}.align", l.c_name)), l.align.to_string(), "alignment of {}", l.c_name);
        for (f, offset) in &l.fields {
            assert_eq!(get(&format!("{}.{f}", l.c_name)), offset.to_string(), "offset of {}.{f}", l.c_name);
        }
    }
    for (m, version, name) in [
        ("MEASUREMENT", Measurement::VERSION, Measurement::TYPE_NAME),
        ("ESTIMATE", Estimate::VERSION, Estimate::TYPE_NAME),
        ("COMMAND", Cmd::VERSION, Cmd::TYPE_NAME),
        ("TRUTH", Truth::VERSION, Truth::TYPE_NAME),
        ("CONTROL", Control::VERSION, Control::TYPE_NAME),
        ("SWARM", SwarmState::VERSION, SwarmState::TYPE_NAME),
    ] {
        assert_eq!(get(&format!("version.{m}")), version.to_string(), "{m} version");
        assert_eq!(get(&format!("type_name.{m}")), name, "{m} type name");
    }
    assert_eq!(get("max_uavs"), protocol::MAX_UAVS.to_string());
    assert_eq!(get("flag_hold"), Cmd::FLAG_HOLD.to_string());
    assert_eq!(get("in_flight"), protocol::ControlKind::IN_FLIGHT.to_string());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn every_field_of_every_type_is_listed() {
    let _scenario = crate::common::scenario(module_path!());
    // A field added to a Rust type without its line here (and in the header) would escape the check: the
    // listed fields must tile the struct (each starts where the previous one ends, up to its size), which
    // also holds only if no padding is hidden.
    let sizes: BTreeMap<&str, Vec<usize>> = BTreeMap::from([
        ("uavloc_stamps", vec![8; 8]),
        ("uavloc_header", vec![4, 4, 8, 8, size_of::<Stamps>()]),
        ("uavloc_name16", vec![16]),
        ("uavloc_measurement", vec![size_of::<Header>(), 4, 1, 1, 2, 128, 64, 64, 64, 64, 64, 64, 64]),
        (
            "uavloc_estimate",
            vec![
                size_of::<Header>(),
                8,
                4,
                1,
                1,
                1,
                1,
                1,
                1,
                1,
                1,
                1,
                1,
                2,
                16,
                32,
                128,
                64,
                16,
                32,
                32,
                64,
                32,
                256,
                32,
                128,
                256,
                size_of::<HeldBursts>(),
                size_of::<TrackWindow>(),
            ],
        ),
        ("uavloc_held_burst", vec![8, 1, 2, 5, 32, 8, 16, 16]),
        ("uavloc_held_bursts", vec![1, 7, 4 * size_of::<HeldBurst>()]),
        ("uavloc_window_burst", vec![8, 1, 1, 6, 128, 64, 64, 64]),
        ("uavloc_track_window", vec![1, 1, 6, 32, 16, 8 * size_of::<WindowBurst>()]),
        ("uavloc_command", vec![size_of::<Header>(), 8, 8, 8, 8, 4, 4, 8, 64, 128, 16, 16, size_of::<StateEcho>()]),
        (
            "uavloc_state_echo",
            vec![
                8,
                1,
                1,
                1,
                1,
                1,
                1,
                1,
                1,
                16,
                32,
                16,
                32,
                32,
                256,
                32,
                128,
                256,
                size_of::<HeldBursts>(),
                size_of::<TrackWindow>(),
            ],
        ),
        ("uavloc_truth", vec![size_of::<Header>(), 16, 4, 4]),
        ("uavloc_swarm_state", vec![size_of::<Header>(), 4, 4, 128, 128, 64, 64, 128, 64, 32, 32]),
        ("uavloc_control", vec![size_of::<Header>(), 8, 8, 4, 4, 8, 16, 16]),
    ]);
    for l in layouts() {
        let field_sizes = &sizes[l.c_name];
        assert_eq!(field_sizes.len(), l.fields.len(), "{}: fields listed", l.c_name);
        let mut end = 0;
        for ((f, offset), size) in l.fields.iter().zip(field_sizes) {
            assert_eq!(*offset, end, "{}.{f} does not start where the field before it ends", l.c_name);
            end += size;
        }
        assert_eq!(end, l.size, "{}: the fields do not fill the struct", l.c_name);
    }
}
