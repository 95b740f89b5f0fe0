"""Command-line argument handling that needs no Blender."""

from rls_addon.cli import build_parser, joined_negative_values


def test_lists_and_ranges_that_start_negative_are_taken_as_values():
    argv = ["study", "s.blend", "--out", "o", "--yaw", "-20:20:20", "--pitch", "-10,0,10", "--roll", "-5"]
    assert joined_negative_values(argv) == [
        "study", "s.blend", "--out", "o", "--yaw=-20:20:20", "--pitch=-10,0,10", "--roll", "-5"]
    args = build_parser().parse_args(joined_negative_values(argv))
    assert (args.yaw, args.pitch, args.roll) == ("-20:20:20", "-10,0,10", -5.0)
    # already joined, or not a list: left as it is
    assert joined_negative_values(["--yaw=-20:20:20", "-x"]) == ["--yaw=-20:20:20", "-x"]
    assert joined_negative_values(["--out", "-20:20:20"]) == ["--out=-20:20:20"]


def test_negative_numbers_with_an_exponent_are_taken_as_values():
    argv = ["scan", "s.blend", "--start-time", "-1e12", "--frames", "1-3"]
    assert joined_negative_values(argv) == [
        "scan", "s.blend", "--start-time=-1e12", "--frames", "1-3"]
    assert build_parser().parse_args(joined_negative_values(argv)).start_time == -1e12
    for value in ("-2.5E-3", "-.5e2", "-3e+4"):
        assert joined_negative_values(["--start-time", value]) == [f"--start-time={value}"]
        got = build_parser().parse_args(joined_negative_values(
            ["scan", "s.blend", "--start-time", value])).start_time
        assert got == float(value)
    # plain negative numbers are argparse's own; an option-like word stays an option
    assert joined_negative_values(["--start-time", "-5"]) == ["--start-time", "-5"]
    assert joined_negative_values(["--start-time", "-e5"]) == ["--start-time", "-e5"]
