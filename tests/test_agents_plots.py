"""Learning-curve figure: step axes labelled 0, 50k, 100k... with no overlapping tick labels."""

import json

import numpy as np
import pytest

from smartcar_gym.agents.plots import format_steps, learning_curve_figure, plot_learning_curve


@pytest.mark.parametrize(("value", "label"), [
    (0, "0"), (500, "500"), (2500, "2.5k"), (75_000, "75k"), (100_000, "100k"),
    (200_704, "200.7k"), (1_250_000, "1.25M"), (-3000, "-3k"),
])
def test_step_counts_as_short_labels(value, label):
    assert format_steps(value) == label


def _run_folder(tmp_path, steps: int):
    """A run of ``steps`` steps: two envs' Monitor files and evaluations every 25k."""
    run_dir = tmp_path / "ppo_run"
    (run_dir / "monitor").mkdir(parents=True)
    (run_dir / "eval").mkdir()
    rng = np.random.default_rng(0)
    for rank in (0, 1):
        rows = [f"{rng.normal():.3f},200,{t:.1f},{int(t > 300)}" for t in range(steps // 400)]
        (run_dir / "monitor" / f"seg0_{rank}.monitor.csv").write_text(
            "#" + json.dumps({"t_start": 0.0}) + "\nr,l,t,is_success\n" + "\n".join(rows) + "\n")
    timesteps = np.arange(25_000, steps + 1, 25_000)
    np.savez(run_dir / "eval" / "evaluations.npz", timesteps=timesteps,
             results=rng.normal(size=(len(timesteps), 4)), ep_lengths=np.full((len(timesteps), 4),
                                                                             200),
             successes=rng.random((len(timesteps), 4)) > 0.5)
    return run_dir


def _overlaps(labels) -> list[tuple[str, str]]:
    boxes = [(t.get_text(), t.get_window_extent()) for t in labels if t.get_text()]
    return [(a, b) for (a, box_a), (b, box_b) in zip(boxes, boxes[1:], strict=False)
            if box_a.x1 > box_b.x0]


def test_learning_curve_steps_axes_read_in_thousands_without_overlap(tmp_path):
    run_dir = _run_folder(tmp_path, 200_000)
    fig = learning_curve_figure(run_dir)
    fig.canvas.draw()  # lays the ticks out as savefig does
    for ax in fig.axes:
        labels = ax.get_xticklabels()
        texts = [t.get_text() for t in labels if t.get_text()]
        assert "100k" in texts and "200k" in texts, texts
        assert all(t == "0" or t.endswith("k") for t in texts), texts
        assert not _overlaps(labels)
        assert ax.xaxis.get_offset_text().get_text() == ""  # no "1e5" beside the axis
    path = plot_learning_curve(run_dir)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
