"""batch.py's progress (bars on a terminal, plain lines in logs) and its final table."""
import io

from cli.progress import PhaseProgress
from cli.summary import Row, table
from core.construct.types import Progress


def _feed(progress, phases):
    for phase, n in phases:
        for i in range(1, n + 1):
            progress(Progress(phase, i, n, 0.1, 30.0 + i, float(n - i)))
    progress.close()


def test_plain_lines_one_per_phase_change_with_time_left():
    out = io.StringIO()
    p = PhaseProgress("ball", stream=out, interval=3600.0, bars=False)
    _feed(p, [("base", 100), ("optimize", 50)])
    p({"phase": "done", "iteration": 50, "total_iterations": 50, "eta_s": 0.0})
    lines = out.getvalue().splitlines()
    assert [ln.split()[1] for ln in lines] == ["base", "optimize", "done"]
    assert lines[1].startswith("[ball] optimize  1/50  PSNR 31.00") and "49 s left" in lines[1]
    assert "left" not in lines[2]


def test_bars_show_phase_count_time_left_and_psnr():
    out = io.StringIO()
    p = PhaseProgress("ball", stream=out, bars=True)
    p(Progress("base", 1, 4, 0.0, float("nan"), 0.0))
    _feed(p, [("optimize", 8)])
    p(Progress("done", 8, 8, 0.1, 38.0, 0.0))
    text = out.getvalue().replace("\r", "\n")
    assert "[ball] base" in text and "4/4" in text      # a phase ends full where the next begins
    assert "[ball] done" not in text
    last = [ln for ln in text.splitlines() if "[ball] optimize" in ln][-1]
    assert "8/8" in last and "PSNR 38.00" in last and "<00:00" in last  # elapsed<left


def test_table_aligns_rows_and_names_failures():
    rows = [Row("bunny.ply", "done", {"base_faces": 4741, "micro_triangles": 138838,
                                      "psnr": 37.5012, "shell_volume": 0.01234,
                                      "export": {"bytes": 1_234_567}, "total_time_s": 376.2}),
            Row("broken.obj", "failed"), Row("demo", "interrupted")]
    lines = table(rows).splitlines()
    assert lines[0].split() == ["input", "result", "base", "micro-tris", "PSNR", "dB", "shell",
                                "MB", "time", "s"]
    assert set(lines[1]) <= {"-", " "}
    assert lines[2].split() == ["bunny.ply", "done", "4741", "138838", "37.50", "0.0123",
                                "1.23", "376"]
    assert lines[3].split() == ["broken.obj", "failed"] and lines[4].split() == ["demo",
                                                                                "interrupted"]
    assert len({len(ln) for ln in lines[:3]}) == 1       # aligned
