"""ctypes mirrors of uavloc's wire messages (include/uavloc/messages.h, docs/wire-format.md).

The layouts equal the Rust `#[repr(C)]` types byte for byte; `check_layout()` compares the sizes with
the ones the wire contract states, and the iceoryx2 type names below are the ones the Rust services are
created with (a mismatch makes opening the service fail instead of misreading it).
"""

import ctypes

MAX_UAVS = 8
MIN_UAVS = 3

MEASUREMENT_VERSION = 2
COMMAND_VERSION = 9
CONTROL_VERSION = 5

# Event id of "a sample was published" on a topic's companion event service (protocol::transport::event_id).
EVENT_SAMPLE = 1
EVENT_PUBLISHER_CREATED = 2
EVENT_PUBLISHER_DROPPED = 3
EVENT_PUBLISHER_DEAD = 4
# The largest event id of a topic's event service (protocol::transport::event_id::MAX).
EVENT_ID_MAX = 4

# Service settings every uavloc topic is created with (protocol::transport); opening with the same ones
# is always compatible.
MAX_PUBLISHERS = 8
MAX_SUBSCRIBERS = 16
SUBSCRIBER_BUFFER = 64
HISTORY = 0


def open_topic(node, name, message_type):
    """The iceoryx2 publish-subscribe service `name` of `message_type` on `node`, opened (or created) with
    the settings every uavloc topic has."""
    import iceoryx2 as iox2

    return (
        node.service_builder(iox2.ServiceName.new(name))
        .publish_subscribe(message_type)
        .max_publishers(MAX_PUBLISHERS)
        .max_subscribers(MAX_SUBSCRIBERS)
        .subscriber_max_buffer_size(SUBSCRIBER_BUFFER)
        .history_size(HISTORY)
        .enable_safe_overflow(True)
        .open_or_create()
    )


COMMAND_FLAG_HOLD = 1
COMMAND_FLAG_CERTIFIED = 2  # the plan carries a safety certificate
COMMAND_FLAG_UNCERTIFIED = 4  # no certified plan existed: the one with the largest minimum margin


class Stamps(ctypes.Structure):
    """Latency stamps, CLOCK_MONOTONIC nanoseconds (0 = not stamped)."""

    _fields_ = [
        ("published_ns", ctypes.c_uint64),
        ("trigger_command_published_ns", ctypes.c_uint64),
        ("trigger_command_received_ns", ctypes.c_uint64),
        ("measurement_published_ns", ctypes.c_uint64),
        ("measurement_received_ns", ctypes.c_uint64),
        ("estimate_published_ns", ctypes.c_uint64),
        ("estimate_received_ns", ctypes.c_uint64),
        ("command_published_ns", ctypes.c_uint64),
    ]


class Header(ctypes.Structure):
    """Common header: layout version, run tag (0: not stated), step, sequence number (strictly increasing
    per publisher), stamps."""

    _fields_ = [
        ("version", ctypes.c_uint32),
        ("run", ctypes.c_uint32),
        ("step", ctypes.c_uint64),
        ("seq", ctypes.c_uint64),
        ("stamps", Stamps),
    ]


class Name16(ctypes.Structure):
    """A short ASCII name, NUL-padded."""

    _fields_ = [("bytes", ctypes.c_uint8 * 16)]

    def text(self) -> str:
        return bytes(self.bytes).rstrip(b"\0").decode("ascii", "replace")


# Measurement.flags
FLAG_SILENT = 1


class Measurement(ctypes.Structure):
    """front end -> estimator, planner, monitor: the burst of step k as the receivers give it.

    arrivals[i] = c * (t_i - t_epoch) in metres for any common epoch, read for the UAVs whose bit is set
    in `heard` (any subset, any of them the reference); a step heard by fewer than two UAVs, or a silent
    one (flags = FLAG_SILENT, heard = 0), still carries every UAV's position and heading.
    """

    _fields_ = [
        ("header", Header),
        ("count", ctypes.c_uint32),
        ("heard", ctypes.c_uint8),
        ("flags", ctypes.c_uint8),
        ("reserved", ctypes.c_uint8 * 2),
        ("uavs", (ctypes.c_double * 2) * MAX_UAVS),
        ("arrivals", ctypes.c_double * MAX_UAVS),
        ("sigmas", ctypes.c_double * MAX_UAVS),
        ("headings", ctypes.c_double * MAX_UAVS),
        ("position_sigmas", ctypes.c_double * MAX_UAVS),
        ("position_bias_sigmas", ctypes.c_double * MAX_UAVS),
        ("clock_sigmas_ns", ctypes.c_double * MAX_UAVS),
        ("clock_bias_sigmas_ns", ctypes.c_double * MAX_UAVS),
    ]

    @staticmethod
    def type_name() -> str:
        return "uavloc::Measurement/v2"


MAX_HELD_BURSTS = 4


class HeldBurst(ctypes.Structure):
    """A burst heard by two UAVs only, held by the estimator for its first fix (part of its state)."""

    _fields_ = [
        ("step", ctypes.c_uint64),
        ("count", ctypes.c_uint8),
        ("uavs", ctypes.c_uint8 * 2),
        ("reserved", ctypes.c_uint8 * 5),
        ("positions", (ctypes.c_double * 2) * 2),
        ("arrival_diff", ctypes.c_double),
        ("sigmas", ctypes.c_double * 2),
        ("bias_sigmas", ctypes.c_double * 2),
    ]


class HeldBursts(ctypes.Structure):
    """The held bursts of an estimator state: `count` of `bursts`, oldest first."""

    _fields_ = [
        ("count", ctypes.c_uint8),
        ("reserved", ctypes.c_uint8 * 7),
        ("bursts", HeldBurst * MAX_HELD_BURSTS),
    ]


MAX_WINDOW_BURSTS = 8


class WindowBurst(ctypes.Structure):
    """One burst of a track's window: the arrivals the estimator kept of it (part of its state)."""

    _fields_ = [
        ("step", ctypes.c_uint64),
        ("count", ctypes.c_uint8),
        ("heard", ctypes.c_uint8),
        ("reserved", ctypes.c_uint8 * 6),
        ("positions", (ctypes.c_double * 2) * MAX_UAVS),
        ("arrivals", ctypes.c_double * MAX_UAVS),
        ("sigmas", ctypes.c_double * MAX_UAVS),
        ("bias_sigmas", ctypes.c_double * MAX_UAVS),
    ]


class TrackWindow(ctypes.Structure):
    """A static emitter's track: the older bursts in information form, the newest raw."""

    _fields_ = [
        ("open", ctypes.c_uint8),
        ("count", ctypes.c_uint8),
        ("reserved", ctypes.c_uint8 * 6),
        ("base_matrix", (ctypes.c_double * 2) * 2),
        ("base_vector", ctypes.c_double * 2),
        ("bursts", WindowBurst * MAX_WINDOW_BURSTS),
    ]


class StateEcho(ctypes.Structure):
    """The estimator's state after `step`, echoed in a Command (a front end may ignore it)."""

    _fields_ = [
        ("step", ctypes.c_uint64),
        ("kind", ctypes.c_uint8),
        ("estimator", ctypes.c_uint8),
        ("model", ctypes.c_uint8),
        ("rejected_run", ctypes.c_uint8),
        ("confirmed", ctypes.c_uint8),
        ("alternative", ctypes.c_uint8),
        ("drop_uavs", ctypes.c_uint8),
        ("drop_run", ctypes.c_uint8),
        ("position", ctypes.c_double * 2),
        ("covariance", (ctypes.c_double * 2) * 2),
        ("velocity", ctypes.c_double * 2),
        ("cross_cov", (ctypes.c_double * 2) * 2),
        ("velocity_cov", (ctypes.c_double * 2) * 2),
        ("bias_sensitivity", (ctypes.c_double * MAX_UAVS) * 4),
        ("alt_mean", ctypes.c_double * 4),
        ("alt_cov", (ctypes.c_double * 4) * 4),
        ("alt_bias_sensitivity", (ctypes.c_double * MAX_UAVS) * 4),
        ("held", HeldBursts),
        ("window", TrackWindow),
    ]


class Command(ctypes.Structure):
    """planner -> front end, monitor: the headings (and where they lead) for step k."""

    _fields_ = [
        ("header", Header),
        ("planner_instance", ctypes.c_uint64),
        ("plan_time_us", ctypes.c_uint64),
        ("active_constraints", ctypes.c_uint64),
        ("violated_constraints", ctypes.c_uint64),
        ("count", ctypes.c_uint32),
        ("flags", ctypes.c_uint32),
        ("objective", ctypes.c_double),
        ("headings", ctypes.c_double * MAX_UAVS),
        ("waypoints", (ctypes.c_double * 2) * MAX_UAVS),
        ("solver", Name16),
        ("objective_name", Name16),
        ("state", StateEcho),
    ]

    @staticmethod
    def type_name() -> str:
        return "uavloc::Command/v9"


class SwarmState(ctypes.Structure):
    """MAVLink bridge -> world, monitor, front ends: the UAVs as their autopilots report them (10 Hz)."""

    LINK_UNKNOWN, LINK_FLYING, LINK_NOT_GUIDED, LINK_QUIET = 0, 1, 2, 3

    _fields_ = [
        ("header", Header),
        ("count", ctypes.c_uint32),
        ("reserved", ctypes.c_uint32),
        ("positions", (ctypes.c_double * 2) * MAX_UAVS),
        ("lat_lon_deg", (ctypes.c_double * 2) * MAX_UAVS),
        ("altitude_m", ctypes.c_double * MAX_UAVS),
        ("headings", ctypes.c_double * MAX_UAVS),
        ("velocities", (ctypes.c_double * 2) * MAX_UAVS),
        ("fix_ns", ctypes.c_uint64 * MAX_UAVS),
        ("link", ctypes.c_uint32 * MAX_UAVS),
        ("rejected", ctypes.c_uint32 * MAX_UAVS),
    ]

    @staticmethod
    def type_name() -> str:
        return "uavloc::SwarmState/v1"


# Sizes stated by docs/wire-format.md (and checked against the Rust types by tests/e2e/wire_layout.rs).
SIZES = {Measurement: 672, Command: 4280, SwarmState: 736}


def check_layout() -> None:
    """Raises if a structure's size or alignment is not the wire contract's."""
    for t, size in SIZES.items():
        if ctypes.sizeof(t) != size or ctypes.alignment(t) != 8:
            raise RuntimeError(
                f"{t.__name__}: {ctypes.sizeof(t)} bytes, alignment {ctypes.alignment(t)}; the wire format says {size}, 8"
            )
