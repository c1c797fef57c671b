/*
 * uavloc wire format: the fixed-layout messages of the uavloc pipeline, for C and C++ front ends that
 * publish or subscribe through iceoryx2's C/C++ API.
 *
 * The layouts equal the Rust `#[repr(C)]` types of `protocol/src/messages.rs` byte for byte; the test
 * `tests/e2e/wire_layout.rs` compiles this header and checks every struct's size and alignment and every
 * field's offset against the Rust types. The contract (units, validation, service names, versions) is
 * docs/wire-format.md. Every padding is spelled out as a `reserved` field: any bit pattern is a value,
 * and receivers validate before they trust one.
 *
 * iceoryx2 type names (the payload type name of each publish/subscribe service; a mismatch fails the
 * open instead of misreading): see the UAVLOC_TYPE_NAME_* macros.
 */
#ifndef UAVLOC_MESSAGES_H
#define UAVLOC_MESSAGES_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Largest number of UAVs a message carries; only the first `count` entries of a per-UAV array are used. */
#define UAVLOC_MAX_UAVS 8
/* Smallest number of UAVs of a valid message. */
#define UAVLOC_MIN_UAVS 3

/* Layout versions (the header's `version` must equal the type's). */
#define UAVLOC_MEASUREMENT_VERSION 2u
#define UAVLOC_ESTIMATE_VERSION 10u
#define UAVLOC_COMMAND_VERSION 9u
#define UAVLOC_TRUTH_VERSION 3u
#define UAVLOC_SWARM_VERSION 1u
#define UAVLOC_CONTROL_VERSION 5u

#define UAVLOC_TYPE_NAME_MEASUREMENT "uavloc::Measurement/v2"
#define UAVLOC_TYPE_NAME_ESTIMATE "uavloc::Estimate/v10"
#define UAVLOC_TYPE_NAME_COMMAND "uavloc::Command/v9"
#define UAVLOC_TYPE_NAME_TRUTH "uavloc::Truth/v3"
#define UAVLOC_TYPE_NAME_SWARM "uavloc::SwarmState/v1"
#define UAVLOC_TYPE_NAME_CONTROL "uavloc::Control/v5"

/* Latency stamps (CLOCK_MONOTONIC, ns; 0 = not stamped) carried forward along one planning cycle. */
typedef struct uavloc_stamps {
    uint64_t published_ns;                 /* when this message was published */
    uint64_t trigger_command_published_ns; /* the command that triggered this step: published */
    uint64_t trigger_command_received_ns;  /* ... and received by the world */
    uint64_t measurement_published_ns;
    uint64_t measurement_received_ns;
    uint64_t estimate_published_ns;
    uint64_t estimate_received_ns;
    uint64_t command_published_ns;
} uavloc_stamps;

/* Common header of every message. */
typedef struct uavloc_header {
    uint32_t version;  /* the type's layout version (UAVLOC_*_VERSION) */
    uint32_t run;      /* the sender's run tag; 0 = not stated (what a front end sends; accepted by all) */
    uint64_t step;     /* planning step k */
    uint64_t seq;      /* strictly increasing per publisher */
    uavloc_stamps stamps;
} uavloc_header;

/* A short ASCII name, NUL-padded. */
typedef struct uavloc_name16 {
    uint8_t bytes[16];
} uavloc_name16;

/* uavloc_measurement.flags */
#define UAVLOC_MEASUREMENT_FLAG_SILENT 1u   /* the emitter was silent: heard must be 0 */

/* front end (emitter-sim) -> estimator, planner, monitor: the burst of step k as the receivers give it.
 * arrivals[i] = c * (t_i - t_epoch) for any common epoch within 1e14 m of the arrivals (only differences
 * are used), read for the UAVs whose bit is set in heard; any subset, any of them the reference. Fewer
 * than two heard (or silent): the estimate is predicted and the swarm still commanded. Positions within
 * +-1e7 m; each UAV's stated range sigma (sigmas with its GNSS and clock sigmas) within 1e-6..1e7 m. */
typedef struct uavloc_measurement {
    uavloc_header header;
    uint32_t count;                           /* UAVs N, 3..=8 */
    uint8_t heard;                            /* bit i: UAV i's arrival is in arrivals[i] */
    uint8_t flags;                            /* UAVLOC_MEASUREMENT_FLAG_* */
    uint8_t reserved[2];
    double uavs[UAVLOC_MAX_UAVS][2];          /* UAV positions as reported at the burst, m (x, y) */
    double arrivals[UAVLOC_MAX_UAVS];         /* arrivals as ranges with a common unknown offset, m */
    double sigmas[UAVLOC_MAX_UAVS];           /* range noise sigma per UAV, m (> 0) */
    double headings[UAVLOC_MAX_UAVS];         /* UAV headings at the measurement, rad */
    double position_sigmas[UAVLOC_MAX_UAVS];  /* GNSS sigma per axis, new every step, m (>= 0) */
    double position_bias_sigmas[UAVLOC_MAX_UAVS]; /* GNSS bias sigma per axis, for the flight, m (>= 0) */
    double clock_sigmas_ns[UAVLOC_MAX_UAVS];  /* clock sigma, new every step, ns (>= 0) */
    double clock_bias_sigmas_ns[UAVLOC_MAX_UAVS]; /* clock bias sigma, for the flight, ns (>= 0) */
} uavloc_measurement;

/* Estimate status (uavloc_estimate.status). */
#define UAVLOC_STATUS_OK 0u
#define UAVLOC_STATUS_AMBIGUOUS 1u
#define UAVLOC_STATUS_FAILED 2u
#define UAVLOC_STATUS_REJECTED 3u
#define UAVLOC_STATUS_PREDICTED 4u   /* no burst heard by two UAVs: the posterior predicted */

/* Bursts an estimate holds before the estimator's first fix. */
#define UAVLOC_MAX_HELD_BURSTS 4

/* A burst heard by two UAVs only, before the estimator's first fix (kept for it). */
typedef struct uavloc_held_burst {
    uint64_t step;                    /* the step of the burst */
    uint8_t count;                    /* UAVs N of the swarm */
    uint8_t uavs[2];                  /* the two UAVs that heard it (ascending) */
    uint8_t reserved[5];
    double positions[2][2];           /* their reported positions, m */
    double arrival_diff;              /* a[uavs[1]] - a[uavs[0]], m */
    double sigmas[2];                 /* their stated sigma, m */
    double bias_sigmas[2];            /* its persistent part, m */
} uavloc_held_burst;

/* The held bursts of an estimator state: `count` of `bursts`, oldest first. */
typedef struct uavloc_held_bursts {
    uint8_t count;
    uint8_t reserved[7];
    uavloc_held_burst bursts[UAVLOC_MAX_HELD_BURSTS];
} uavloc_held_bursts;

/* Bursts a track's window keeps raw. */
#define UAVLOC_MAX_WINDOW_BURSTS 8

/* One burst of a track's window: the arrivals the estimator kept of it, as it fused them. */
typedef struct uavloc_window_burst {
    uint64_t step;                    /* the step of the burst */
    uint8_t count;                    /* UAVs N of the swarm */
    uint8_t heard;                    /* bit i: UAV i's arrival kept (two or more) */
    uint8_t reserved[6];
    double positions[UAVLOC_MAX_UAVS][2]; /* reported positions, m */
    double arrivals[UAVLOC_MAX_UAVS];     /* arrivals (a common offset), m; read where kept */
    double sigmas[UAVLOC_MAX_UAVS];       /* the sigma each was fused with, m */
    double bias_sigmas[UAVLOC_MAX_UAVS];  /* its persistent part, m */
} uavloc_window_burst;

/* A static emitter's track: the older bursts in information form, the newest raw. */
typedef struct uavloc_track_window {
    uint8_t open;                     /* 1: the track has a window */
    uint8_t count;                    /* bursts held raw (0..8) */
    uint8_t reserved[6];
    double base_matrix[2][2];         /* Lambda of the older bursts, 1/m^2, row-major */
    double base_vector[2];            /* eta = Lambda x_b, 1/m */
    uavloc_window_burst bursts[UAVLOC_MAX_WINDOW_BURSTS];
} uavloc_track_window;

/* estimator -> planner, monitor: the emitter estimate of step k and the geometry it was computed for. */
typedef struct uavloc_estimate {
    uavloc_header header;
    uint64_t instance;                /* estimator process instance id */
    uint32_t count;                   /* UAVs N */
    uint8_t status;                   /* UAVLOC_STATUS_* */
    uint8_t estimator;                /* 0 snapshot (Chan), 1 fused */
    uint8_t model;                    /* 0 static, 1 constant velocity */
    uint8_t rejected_run;             /* fused: snapshots rejected in a row */
    uint8_t heard;                    /* bit i: UAV i's arrival was in the measurement */
    uint8_t outliers;                 /* bit i: UAV i's arrival dropped as an outlier */
    uint8_t confirmed;                /* fused: bursts fused whole since the track started (saturating) */
    uint8_t alternative;              /* fused: 1 when Chan's other root is pending (alt_* below) */
    uint8_t drop_uavs;                /* fused: UAVs dropped burst after burst (bit i: UAV i; v8) */
    uint8_t drop_run;                 /* fused: how many bursts in a row dropped them (v8) */
    uint8_t reserved[2];
    double position[2];               /* m; failed: the standing estimate, or NaN */
    double covariance[2][2];          /* m^2, row-major */
    double uavs[UAVLOC_MAX_UAVS][2];  /* m */
    double headings[UAVLOC_MAX_UAVS]; /* rad */
    double velocity[2];               /* m/s (constant velocity; else 0) */
    double cross_cov[2][2];           /* position-velocity covariance, m^2/s */
    double velocity_cov[2][2];        /* m^2/s^2 */
    double sigmas[UAVLOC_MAX_UAVS];   /* m: stated sigma (range, GNSS, clock) of the measurement; all 0: not stated */
    double bias_cov[2][2];            /* m^2: the persistent GNSS/clock errors' covariance, added to covariance */
    double bias_sensitivity[4][UAVLOC_MAX_UAVS]; /* d(estimate - truth)/d(bias of UAV j): rows x, y, vx, vy */
    double alt_mean[4];               /* the pending root: x, y (m), vx, vy (m/s) */
    double alt_cov[4][4];             /* its covariance, row-major */
    double alt_bias_sensitivity[4][UAVLOC_MAX_UAVS]; /* its bias sensitivity */
    uavloc_held_bursts held;          /* fused, before the first fix: the bursts held for it (v9) */
    uavloc_track_window window;       /* fused, static emitter: the track's window (v10) */
} uavloc_estimate;

/* uavloc_command.flags */
#define UAVLOC_COMMAND_FLAG_HOLD 1u
#define UAVLOC_COMMAND_FLAG_CERTIFIED 2u   /* the plan carries a safety certificate */
#define UAVLOC_COMMAND_FLAG_UNCERTIFIED 4u /* no certified plan existed: the largest minimum margin */

/* uavloc_state_echo.kind */
#define UAVLOC_STATE_NONE 0u   /* a hold: planned from no estimate */
#define UAVLOC_STATE_STATE 1u  /* the estimator's state is in the fields */
#define UAVLOC_STATE_EMPTY 2u  /* no usable estimate yet after `step` */

/* The estimator's state after step `step`, echoed by the planner from the estimate it planned from. */
typedef struct uavloc_state_echo {
    uint64_t step;
    uint8_t kind;                       /* UAVLOC_STATE_* */
    uint8_t estimator;                  /* as uavloc_estimate */
    uint8_t model;
    uint8_t rejected_run;
    uint8_t confirmed;                  /* as uavloc_estimate (0: a provisional track) */
    uint8_t alternative;                /* as uavloc_estimate */
    uint8_t drop_uavs;                  /* as uavloc_estimate (v7 command) */
    uint8_t drop_run;                   /* as uavloc_estimate (v7 command) */
    double position[2];                 /* m */
    double covariance[2][2];            /* m^2 */
    double velocity[2];                 /* m/s */
    double cross_cov[2][2];             /* m^2/s */
    double velocity_cov[2][2];          /* m^2/s^2 */
    double bias_sensitivity[4][UAVLOC_MAX_UAVS]; /* as uavloc_estimate */
    double alt_mean[4];                 /* as uavloc_estimate */
    double alt_cov[4][4];
    double alt_bias_sensitivity[4][UAVLOC_MAX_UAVS];
    uavloc_held_bursts held;            /* as uavloc_estimate (v8 command) */
    uavloc_track_window window;         /* as uavloc_estimate (v9 command) */
} uavloc_state_echo;

/* planner -> front end (emitter-sim), monitor: the headings for step k. */
typedef struct uavloc_command {
    uavloc_header header;
    uint64_t planner_instance;          /* planner process instance id */
    uint64_t plan_time_us;              /* planning compute time, us */
    uint64_t active_constraints;        /* bit mask of active constraints (see docs/wire-format.md) */
    uint64_t violated_constraints;      /* bit mask of violated ones */
    uint32_t count;                     /* UAVs N */
    uint32_t flags;                     /* 0 a plan, UAVLOC_COMMAND_FLAG_HOLD a hold */
    double objective;                   /* criterion value at the waypoints (-1: not finite) */
    double headings[UAVLOC_MAX_UAVS];   /* commanded headings, rad */
    double waypoints[UAVLOC_MAX_UAVS][2]; /* where they lead after one interval, m */
    uavloc_name16 solver;               /* e.g. "pso" */
    uavloc_name16 objective_name;       /* e.g. "analytical" */
    uavloc_state_echo state;            /* the estimator's state it was planned from (v4; v5 bias_sensitivity; v6 alt_*; v7 drop_*) */
} uavloc_command;

/* uavloc_truth.previous_command */
#define UAVLOC_PREVIOUS_NONE 0u
#define UAVLOC_PREVIOUS_FLOWN 1u
#define UAVLOC_PREVIOUS_MISSED 2u

/* world -> monitor: the true emitter at step k (absent with an external front end). */
typedef struct uavloc_truth {
    uavloc_header header;
    double position[2];        /* m */
    uint32_t previous_command; /* what became of step k-1's command: UAVLOC_PREVIOUS_* */
    uint32_t multipath;        /* bit i: UAV i's arrival came by a reflection (the world's truth) */
} uavloc_truth;

/* uavloc_swarm_state.link[i] */
#define UAVLOC_LINK_UNKNOWN 0u    /* nothing heard from the autopilot yet */
#define UAVLOC_LINK_FLYING 1u     /* armed, guided, with a fix: it flies the commanded targets */
#define UAVLOC_LINK_NOT_GUIDED 2u /* heard, but not armed or not in a guided mode: no target sent */
#define UAVLOC_LINK_QUIET 3u      /* nothing heard for the bridge's link timeout: the last fix ages */

/* MAVLink bridge -> world (--uavs autopilots), monitor, front ends: the UAVs as their autopilots report
   them, at the bridge's rate (10 Hz); header.step is the step of the last command flown. */
typedef struct uavloc_swarm_state {
    uavloc_header header;
    uint32_t count;                           /* UAVs N, 3..=8 */
    uint32_t reserved;
    double positions[UAVLOC_MAX_UAVS][2];     /* the run's plane (x east, y north), m; valid when fix_ns != 0 */
    double lat_lon_deg[UAVLOC_MAX_UAVS][2];   /* the same, WGS84 [lat, lon], degrees */
    double altitude_m[UAVLOC_MAX_UAVS];       /* as GLOBAL_POSITION_INT.alt, m */
    double headings[UAVLOC_MAX_UAVS];         /* rad, counter-clockwise from east */
    double velocities[UAVLOC_MAX_UAVS][2];    /* ground velocity (east, north), m/s */
    uint64_t fix_ns[UAVLOC_MAX_UAVS];         /* when the fix was received, CLOCK_MONOTONIC ns; 0 = never */
    uint32_t link[UAVLOC_MAX_UAVS];           /* UAVLOC_LINK_* */
    uint32_t rejected[UAVLOC_MAX_UAVS];       /* telemetry refused so far */
} uavloc_swarm_state;

/* uavloc_control.kind */
#define UAVLOC_CONTROL_HELLO 0u
#define UAVLOC_CONTROL_TAKEOVER 1u
#define UAVLOC_CONTROL_SHUTDOWN 2u
#define UAVLOC_CONTROL_PROGRESS 3u
#define UAVLOC_CONTROL_REPLAY 4u
#define UAVLOC_CONTROL_STATUS 5u
#define UAVLOC_CONTROL_STATE 6u
#define UAVLOC_CONTROL_RUN 7u
/* The step of a replay request that asks for the step in flight only. */
#define UAVLOC_CONTROL_IN_FLIGHT UINT64_MAX

/* every process -> every process: hello, take-over, shutdown, progress, replay, status, state, run. */
typedef struct uavloc_control {
    uavloc_header header;
    uint64_t instance;     /* sender instance id */
    uint64_t started_ns;   /* sender start time, CLOCK_MONOTONIC ns (orders two instances of a role) */
    uint32_t kind;         /* UAVLOC_CONTROL_* */
    uint32_t reserved;
    uint64_t run;          /* the sender's scenario fingerprint; 0: the sender has none */
    uavloc_name16 role;    /* "emitter-sim", "estimator", "planner", "monitor", "launch" */
    uavloc_name16 detail;  /* free text, e.g. "pso/analytical" */
} uavloc_control;

#ifdef __cplusplus
}
#endif

#endif /* UAVLOC_MESSAGES_H */
