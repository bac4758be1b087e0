"""Progress lines: the first iteration prints at once, then at most every `every_s` seconds;
`run` reports its mapping calls through them."""
import io

from nicer_stream.runtime.progress import Progress
from nicer_stream.runtime.slam_run import RunRequest, run_slam


def test_first_call_prints_then_at_most_every_interval_and_at_the_end():
    now = [100.0]
    out = io.StringIO()
    p = Progress("mapping @ frame 5", every_s=3.0, stream=out, clock=lambda: now[0])
    lines = []
    for i, dt in enumerate([0.5, 1.0, 1.0, 1.0, 0.5, 0.5]):  # seconds taken by each of 6 iterations
        now[0] += dt
        p(i, 6, 0.25)
        lines.append(out.getvalue().count("\n"))
    # Printed after the first iteration (0.5 s in), at 3.5 s (3 s after it) and at the end.
    assert lines == [1, 1, 1, 2, 2, 3]
    first, second, last = out.getvalue().splitlines()
    assert first == "mapping @ frame 5 1/6 loss 0.2500 0s eta 2s"  # 0.5 s per iteration, 5 to go
    assert second.startswith("mapping @ frame 5 4/6 ") and last.startswith("mapping @ frame 5 6/6 ")
    assert last.endswith("eta 0s")


def test_run_reports_every_mapping_call_on_stderr(tmp_path, tiny_config, capsys):
    # 3 frames with near-GT priors (oracle:clean, GT flow): held for the two-view start until the end, which starts
    # from frames 0 and 2; then the closing call.
    run_slam(RunRequest(source="synthetic:room?frames=3", out_dir=tmp_path / "out", priors="oracle:clean",
                        config_file=str(tiny_config)))
    cap = capsys.readouterr()
    assert cap.out.splitlines()[0].startswith("opening synthetic:room?frames=3 ")
    err = [ln for ln in cap.err.splitlines() if "mapping" in ln]
    assert err[0].startswith("first mapping (frames 0,2) 1/5 loss ")  # tiny config: first_iters = 5
    assert any(ln.startswith("first mapping (frames 0,2) 5/5 ") for ln in err)
    assert any(ln.startswith("closing mapping @ frame 2 4/4 ") for ln in err)  # final_iters = 4
    # the end's renders (frames 0 and the last, --render-every 10) and the mesh each announce themselves
    out = cap.out.splitlines()
    assert out.index("writing outputs: 2 renders and the mesh") < out.index("writing outputs: render 1/2 (frame 0)")
    assert out.index("writing outputs: render 2/2 (frame 2)") < next(
        i for i, ln in enumerate(out) if ln.startswith("writing outputs: the mesh ("))
