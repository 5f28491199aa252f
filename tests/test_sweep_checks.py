"""``plate sweep`` against a plate whose telemetry never follows the carrier: one line saying so, not a traceback.
The plate is scripted on a real pty (its telemetry says the same carrier whatever it is told)."""

from conftest import assert_one_line_error, run_cli
from scripted_plate import PROFILE, ScriptedPlate


def test_a_plate_that_does_not_follow_the_carrier_is_said_in_one_line(tmp_path):
    with ScriptedPlate(enabled_follows=True) as plate:  # its telemetry always says the profile's resonance
        result = run_cli("plate", "sweep", "--device", f"serial:{plate.path}", "--profile", "sim-plate",
                         "-o", tmp_path / "p.toml",
                         "--from-hz", PROFILE.resonance_hz + 500, "--to-hz", PROFILE.resonance_hz + 1500,
                         "--steps", 5, timeout=300)
    line = assert_one_line_error(result)
    assert "the plate driver does not follow the carrier: set to" in line, line
    assert f"its telemetry said {PROFILE.resonance_hz:.1f} Hz for 25 frames" in line, line
    assert list(tmp_path.iterdir()) == []
