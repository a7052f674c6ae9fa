"""The report's figures: reused when nothing changed, drawn the same beside a worker process,
legends and labels inside, configurations told apart by colour and marker, what a figure
leaves out said, the scenario picture and the scorecard picture; on a small real suite
(conftest.py)."""

import shutil

import scenarios
from reports.run.plan import plan
from reports.run.runner import run_suite
from reports.store.format import fmt
from reports.store.results import read_results


def test_figures_are_reused_when_nothing_changed(folder):
    """A report regenerated from an unchanged store draws no figure again."""
    from reports.report.build import build_report

    pngs = sorted((folder / "plots").glob("*.png"))
    # the scenario picture, errors, rates, convergence, work-precision for two scenarios, but
    # no rates figure for free_tumbling (every configuration within 1 %: a sentence instead)
    assert len(pngs) == 9
    pngs += [folder / "scorecard.png", folder / "scorecard.svg"]
    before = {p: p.stat().st_mtime_ns for p in pngs}
    build_report(folder)
    assert {p: p.stat().st_mtime_ns for p in pngs} == before


def test_figures_drawn_beside_a_worker_process_are_the_serial_ones(folder, tmp_path, monkeypatch):
    """With a worker process (two cores), this process draws the scorecard picture and takes
    scenarios as well: every figure is drawn once, into the same files, byte for byte, as
    when one process draws them all."""
    from reports.report import figures

    made = {}
    for name, cores in (("serial", 1), ("pooled", 2)):
        dst = tmp_path / name
        shutil.copytree(folder, dst, ignore=shutil.ignore_patterns("plots", "scorecard.*"))
        monkeypatch.setenv("DIRECTOR_BENCH_CACHE", str(tmp_path / f"cache-{name}"))  # drawn
        monkeypatch.setattr(figures, "_cpus", lambda cores=cores: cores)
        monkeypatch.setattr(figures, "PARALLEL_FROM", 2)  # the folder has two scenarios
        made[name] = figures.report_figures(read_results(dst), dst)
    (serial, card), (pooled, pooled_card) = made["serial"], made["pooled"]
    names = {sc: [p.name for p in ps] for sc, ps in serial.items()}
    assert names == {sc: [p.name for p in ps] for sc, ps in pooled.items()}
    assert sorted(names) == ["cone_top", "free_tumbling"] and all(names.values())
    for sc, ps in serial.items():
        for p, q in zip(ps, pooled[sc], strict=True):
            assert p.read_bytes() == q.read_bytes(), p.name
            assert p.with_suffix(".json").read_bytes() == q.with_suffix(".json").read_bytes()
    assert (
        [p.name for p in card]
        == [p.name for p in pooled_card]
        == ["scorecard.png", "scorecard.svg"]
    )
    assert card[0].read_bytes() == pooled_card[0].read_bytes()


def test_figures_without_timings_are_reused_from_another_folder(folder, tmp_path, monkeypatch):
    """A second folder with the same results (another run of the same code: timings and
    clock times differ) copies every figure but the work-precision one from the user's
    cache, byte for byte; a series file that differs (a planted change) is drawn anew."""
    import pandas as pd
    import pyarrow.parquet as pq

    from reports.report import figures

    monkeypatch.setenv("DIRECTOR_BENCH_CACHE", str(tmp_path / "cache"))
    first = tmp_path / "first"
    shutil.copytree(folder, first, ignore=shutil.ignore_patterns("plots", "scorecard.*"))
    made = figures.all_plots(read_results(first), first)
    drawn = []
    real = figures.scenario_plot

    def counting(kind, df, cache, out, scenario, styles, failed=None):
        drawn.append((scenario, kind))
        return real(kind, df, cache, out, scenario, styles, failed)

    monkeypatch.setattr(figures, "scenario_plot", counting)
    second = tmp_path / "second"
    shutil.copytree(folder, second, ignore=shutil.ignore_patterns("plots", "scorecard.*"))
    df = read_results(second)
    df["engine_time_s"] *= 3.0  # another run's timings
    df["finished_at"] = "2030-01-01T00:00:00+00:00"
    again = figures.all_plots(df, second)
    assert sorted(drawn) == [("cone_top", "work_precision"), ("free_tumbling", "work_precision")]
    for sc, paths in made.items():
        assert [p.name for p in paths] == [p.name for p in again[sc]]
        for p, q in zip(paths, again[sc], strict=True):
            if "work_precision" not in p.name:
                assert p.read_bytes() == q.read_bytes(), p.name
    # a planted change in one run's series: that scenario's figures are drawn again
    row = df[(df["scenario"] == "cone_top") & (df["trajectory"] != "")].iloc[0]
    path = second / row["trajectory"]
    table = pq.read_table(path)
    series = table.to_pandas()
    series["t"] = series["t"] * 1.0 + 1e-9
    pq.write_table(pa_table(series, table.schema.metadata), path)
    drawn.clear()
    third = tmp_path / "third"
    shutil.copytree(second, third, ignore=shutil.ignore_patterns("plots", "scorecard.*"))
    figures.all_plots(df, third)
    assert ("cone_top", "errors") in drawn and ("free_tumbling", "errors") not in drawn
    assert isinstance(df, pd.DataFrame)


def pa_table(frame, metadata):
    import pyarrow as pa

    return pa.Table.from_pandas(frame, preserve_index=False).replace_schema_metadata(metadata)


def test_figures_are_reused_when_the_folder_is_named_relative_or_absolute(folder, monkeypatch):
    """The same folder named once relative to the working directory and once absolute is
    the same folder: nothing is drawn again."""
    from reports.report.build import build_report

    pngs = sorted((folder / "plots").glob("*.png"))
    before = {p: p.stat().st_mtime_ns for p in pngs}
    monkeypatch.chdir(folder.parent)
    build_report(folder.name)
    build_report(folder.resolve())
    assert {p: p.stat().st_mtime_ns for p in pngs} == before


def _capture_figures(monkeypatch):
    """Keep each figure the plot functions save (instead of closing it) for inspection: in
    every figure module that writes or closes figures."""
    from reports.report import canvas, pictures, scorecard_plot

    kept = []
    real = canvas._write_png

    def keep(fig, path, **kw):
        real(fig, path, **kw)
        kept.append((path, fig))

    for mod in (canvas, pictures, scorecard_plot):
        monkeypatch.setattr(mod, "_write_png", keep)
        monkeypatch.setattr(mod, "_plt", _no_close(canvas._plt))
    return kept


def _no_close(real_plt):
    def wrapped():
        plt = real_plt()

        class NoClose:
            def __getattr__(self, name):
                return getattr(plt, name)

            def close(self, fig=None):
                pass

        return NoClose()

    return wrapped


def _outside(fig, path) -> list:
    """The legends, titles, axis labels and drawn tick labels of a figure that reach beyond
    the image saved from it (1 px of slack), by matplotlib's own extents."""
    r = fig.canvas.get_renderer()
    box = fig.bbox
    if path.name == "scorecard.png":  # saved with its tight box: compare with that
        box = fig.get_tightbbox(r).padded(0.1).transformed(fig.dpi_scale_trans)
    texts = [("figure legend", leg.get_window_extent(r)) for leg in fig.legends]
    for ax in fig.axes:
        if ax.get_legend() is not None:
            texts.append(("legend", ax.get_legend().get_window_extent(r)))
        if ax.name == "3d":
            continue
        lo, hi = sorted(ax.get_ylim())
        drawn = [  # the tick labels drawn: those of ticks within the axes' range
            tk.label1 for tk in ax.yaxis.get_major_ticks() if lo <= tk.get_loc() <= hi
        ]
        for t in (ax.title, ax.xaxis.label, ax.yaxis.label, *drawn):
            if t.get_text() and t.get_visible():
                texts.append((t.get_text(), t.get_window_extent(r)))
    return [
        (path.name, what, ext)
        for what, ext in texts
        if not (ext.x0 >= box.x0 - 1 and ext.x1 <= box.x1 + 1 and ext.y0 >= box.y0 - 1
                and ext.y1 <= box.y1 + 1)
    ]  # fmt: skip


LONG = "RK4 with a long display name (error-controlled, for this test)"


def test_every_legend_and_label_lies_inside_its_figure(folder, df, tmp_path, monkeypatch):
    """Every figure of a scenario, with one configuration given a long display name: the
    legend, the tick labels, the axis labels and the titles lie inside the saved figure
    (matplotlib's own extents), whatever the label lengths; the figure's hover file names
    the long configuration."""
    import json

    from reports.report import canvas, figures, scorecard_plot

    df = df.copy()
    df.loc[(df["engine"] == "mujoco") & (df["integrator"] == "RK4"), "integrator"] = LONG
    kept = _capture_figures(monkeypatch)
    styles, cache = canvas.Styles(df), canvas.SeriesCache(folder)
    for kind in figures.KINDS:
        figures.scenario_plot(kind, df, cache, tmp_path, "cone_top", styles)
    scorecard_plot.scorecard_figure(df, tmp_path)
    assert len(kept) == 6
    for path, fig in kept:
        assert _outside(fig, path) == []
    errors = json.loads((tmp_path / "cone-top__errors.json").read_text())
    labels = {ln["label"] for ln in errors["lines"]}
    assert any(LONG in lab for lab in labels), labels
    for ln in errors["lines"]:
        for path in ln["paths"]:
            assert all(0 <= x <= 1 and 0 <= y <= 1 for x, y in path)
    assert "cone_top" in errors["alt"] and "diverged" in errors["alt"]


def test_the_legend_check_catches_a_cut_legend(folder, df, tmp_path, monkeypatch):
    """The check above fails on a figure that is not fitted around its legend (the figure
    left at its first size): the long label reaches beyond the image."""
    from reports.report import canvas, plots

    df = df.copy()
    df.loc[(df["engine"] == "mujoco") & (df["integrator"] == "RK4"), "integrator"] = LONG
    kept = _capture_figures(monkeypatch)
    monkeypatch.setattr(plots, "_new_figure", _narrow(canvas._new_figure))
    monkeypatch.setattr(canvas, "_fit", lambda fig, notes="": None)
    plots.work_precision_plot(df, tmp_path, "cone_top", canvas.Styles(df))
    ((path, fig),) = kept
    assert any(what == "legend" for _, what, _ in _outside(fig, path))


def _narrow(real):
    """``_new_figure`` with the figure only 1.5 in wider than its axes."""

    def new(*args, **kw):
        fig, axes = real(*args, **kw)
        w, h = fig.get_size_inches()
        fig.set_size_inches(1.0 + 5.6 + 1.5, h)
        for ax in axes:
            p = ax.get_position()
            ax.set_position([1.0 / 8.1, p.y0, 5.6 / 8.1, p.height])
        return fig, axes

    return new


def _overlapping_texts(fig) -> list:
    """The pairs of visible texts drawn on a figure's axes (annotations, ax.text) whose boxes
    overlap, by matplotlib's own extents."""
    r = fig.canvas.get_renderer()
    boxes = [
        (t.get_text(), t.get_window_extent(r))
        for ax in fig.axes
        for t in ax.texts
        if t.get_visible() and t.get_text()
    ]
    return [
        (a, b) for i, (a, ba) in enumerate(boxes) for b, bb in boxes[i + 1 :] if ba.overlaps(bb)
    ]


def test_each_diverged_configuration_is_told_apart_on_the_errors_figure(tmp_path, monkeypatch):
    """heavy_top at dt = 1e-3 s, where MuJoCo's Euler diverges at 2.58 s and Drake's
    semi-explicit Euler at 1.64 s (the default suite's numbers): the figure's texts do not
    overlap, and each configuration's legend entry carries its own divergence time."""
    from reports.report import canvas, plots

    sc = scenarios.load("heavy_top").replace(dt_sweep=(1e-3,))
    specs = plan([sc], ("exact", "mujoco", "drake"), ("reference", "Euler", "semi_explicit_euler"))
    run_suite(specs, tmp_path, progress=False)
    df = read_results(tmp_path)
    diverged = df[df["status"] == "diverged"]
    assert len(diverged) == 2 and diverged["t_diverged"].nunique() == 2
    kept = _capture_figures(monkeypatch)
    plots.errors_plot(df, canvas.SeriesCache(tmp_path), tmp_path, "heavy_top", canvas.Styles(df))
    ((path, fig),) = kept
    assert _overlapping_texts(fig) == []
    assert _outside(fig, path) == []
    legend = [" ".join(t.get_text().split()) for t in fig.axes[0].get_legend().get_texts()]
    for r in diverged.to_dict("records"):
        (entry,) = [lab for lab in legend if lab.startswith(f"{r['engine']} {r['integrator']}")]
        assert f"diverged at {fmt(r['t_diverged'])} s" in entry, (entry, r["t_diverged"])


def test_figures_name_what_they_leave_out(folder, df, tmp_path):
    """A configuration not drawn (never within 0.1 rad, no run finished) or cut off at a
    panel's top is named under the figure, not counted."""
    from reports.report import canvas, plots

    plots.work_precision_plot(df, tmp_path, "cone_top", canvas.Styles(df))
    meta = canvas.figure_meta(tmp_path / "cone-top__work_precision.png")
    # semi-implicit Euler diverges on cone_top at both steps: no finished run to draw
    euler = df[(df["scenario"] == "cone_top") & (df["integrator"] == "Euler")]
    assert set(euler["status"]) == {"diverged"}
    assert "not drawn" in meta["alt"] and "mujoco Euler" in meta["alt"]


def test_a_rates_figure_of_the_reference_alone_is_a_sentence_instead(folder, df, tmp_path):
    """free_tumbling here: every configuration's W error stays within 1 % of max |W| of the
    reference (checked on the stored metric and the reference's own series), so no rates
    figure is drawn and the report says why in one sentence; cone_top, where mujoco Euler
    diverges, keeps its figure and no such sentence."""
    import html as htmlmod

    import numpy as np

    from reports.report import canvas, plots
    from reports.store.results import reference_rows

    cache = canvas.SeriesCache(folder)
    free = df[df["scenario"] == "free_tumbling"]
    ref = cache.get(free[reference_rows(free)].iloc[0])
    wmax = float(np.max(np.abs(np.column_stack([ref["wx"], ref["wy"], ref["wz"]]))))
    runs = free[~reference_rows(free)]
    assert len(runs) >= 3 and (runs["omega_error_max"] <= 0.01 * wmax).all()
    styles = canvas.Styles(df)
    assert plots.rates_plot(df, cache, tmp_path, "free_tumbling", styles) is None
    assert plots.rates_plot(df, cache, tmp_path, "cone_top", styles) is not None
    assert not (folder / "plots" / "free-tumbling__rates.png").exists()
    note = plots.rates_left_out(df, cache, "free_tumbling")
    assert (
        note.startswith("No rates figure: the W error of all ") and f"({fmt(wmax)} rad/s)" in note
    )
    assert plots.rates_left_out(df, cache, "cone_top") == ""
    md = (folder / "report.md").read_text()
    free_md = md.split("### free_tumbling")[1]
    assert note in free_md and note not in md.split("### free_tumbling")[0]
    assert htmlmod.escape(note) in (folder / "report.html").read_text()


def test_scenario_box_has_the_scenario_s_moments():
    """The box drawn for a body has its mass and principal moments: its inertia, integrated
    by the midpoint rule on a 40^3 grid (an independent quadrature, relative error of order
    1/40^2 = 6e-4), matches the scenario's moments to 1e-3."""
    import numpy as np

    from reports.report.pictures import body_box

    for name in ("dzhanibekov", "heavy_top", "gazebo_boxes_complex", "pendulum_through_vertical"):
        sc = scenarios.load(name)
        half = body_box(sc)
        n = 40
        grids = [(np.arange(n) + 0.5) / n * 2 * h - h for h in half]
        x, y, z = np.meshgrid(*grids, indexing="ij")
        dm = sc.mass / x.size
        moments = [
            float(np.sum(y**2 + z**2) * dm),
            float(np.sum(x**2 + z**2) * dm),
            float(np.sum(x**2 + y**2) * dm),
        ]
        assert np.allclose(moments, sc.inertia, rtol=1e-3), (name, moments, sc.inertia)


def test_scenario_figures_for_the_docs(tmp_path):
    """``python -m reports.report.pictures --scenario-figures DIR NAME`` writes a small PNG per
    scenario; an unknown name is an error naming it."""
    from reports.report.pictures import main

    assert main(["--scenario-figures", str(tmp_path), "cone_top"]) == 0
    png = tmp_path / "scenario_cone_top.png"
    assert png.exists() and png.stat().st_size < 60_000
    assert main(["--scenario-figures", str(tmp_path), "no_such_scenario"]) == 2


def test_every_configuration_has_a_colour_of_its_own(df):
    """No two configurations of a folder share a colour (the director's four schemes were
    once all one blue)."""
    from reports.report import canvas

    styles = canvas.Styles(df)
    configs = {(e, i) for e, i in zip(df["engine"], df["integrator"], strict=True)} - {
        ("exact", "reference")
    }
    colours = [styles.of({"engine": e, "integrator": i, "family": ""})["color"] for e, i in configs]
    assert len(configs) >= 6 and len(set(colours)) == len(configs)


def test_configurations_whose_colours_look_alike_have_different_markers():
    """The palette's second ten colours repeat the hues of the first ten (#2ca02c and #31a354
    are both green): configuration k and k + 10 must not also share a marker, or a figure
    whose runs show as markers only (a one-step work-precision point) cannot tell them apart.
    No two of 40 configurations share both colour and marker."""
    import pandas as pd

    from reports.report import canvas

    df = pd.DataFrame(
        {"engine": [f"e{k:02d}" for k in range(40)], "integrator": "x", "family": "f"}
    )
    styles = canvas.Styles(df)
    looks = [
        (s["color"], s["marker"])
        for s in (styles.of(r, always_marker=True) for r in df.to_dict("records"))
    ]
    assert len(set(looks)) == 40
    assert all(looks[k][1] != looks[k + 10][1] for k in range(30))


def test_scorecard_picture_is_written_as_png_and_svg_with_text(folder):
    """The scorecard picture for a README: a PNG and an SVG whose words are text (found by
    search, small), naming every scenario and configuration."""
    svg = (folder / "scorecard.svg").read_text()
    assert (folder / "scorecard.png").stat().st_size > 10_000
    for word in ("cone_top", "free_tumbling", "director rattle4", "pinocchio + suite RKMK4"):
        assert word in svg, word


def test_scorecard_figure_is_as_wide_as_its_content(df, tmp_path):
    """One scenario makes a narrow scorecard picture (its title and legend wrap to the label
    column and one column of cells, 2.5 + 1.3 in), not one as wide as a one-line title
    (8.8 in before); more scenarios make it wider."""
    from PIL import Image

    from reports.report.canvas import DPI
    from reports.report.scorecard_plot import scorecard_figure

    widths = {}
    for n, names in ((1, ["free_tumbling"]), (2, ["free_tumbling", "cone_top"])):
        (tmp_path / str(n)).mkdir()
        png, _ = scorecard_figure(df[df["scenario"].isin(names)], tmp_path / str(n))
        widths[n] = Image.open(png).size[0] / DPI
    # 1.5 in for configuration labels longer than the label column (they are never cut)
    assert widths[1] < 2.5 + 1.3 + 1.5, widths
    assert widths[2] > widths[1] + 1.0, widths


def test_scenario_picture_draws_the_body_stored_in_the_folder(folder, df, tmp_path, monkeypatch):
    """The scenario picture takes the body from the folder (stored beside the exact run's
    trajectory), not from the scenario library: with the library out of reach it is drawn
    all the same, and the stored body is the scenario file's."""
    import numpy as np

    from reports.report import canvas, pictures

    sc = scenarios.load("cone_top")
    monkeypatch.setattr(pictures, "library_scenario", lambda row: None)
    cache = canvas.SeriesCache(folder)
    exact = df[(df["scenario"] == "cone_top") & (df["engine"] == "exact")]
    row = exact.to_dict("records")[0]
    body = cache.body(row)
    assert body.name == sc.name and body.mass == sc.mass
    assert np.array_equal(body.inertia, sc.inertia) and np.array_equal(body.pivot, sc.pivot)
    assert np.array_equal(body.omega_body, sc.omega_body)
    path = pictures.scenario_plot_from_results(df, cache, tmp_path, "cone_top")
    assert path is not None and path.exists()


def test_the_text_caching_backend_draws_the_pixels_agg_draws(tmp_path):
    """reports.report.agg_text caches string layouts and glyph bitmaps across figures: a figure
    of texts at fractional positions, sizes, weights, a rotated label, mathtext, non-ASCII
    (superscripts, marks) must come out pixel for pixel as matplotlib's own Agg draws it,
    the first time (caches filling) and the second (caches hit)."""
    import matplotlib
    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from reports.report import agg_text

    def draw(canvas_class):
        fig = Figure(figsize=(4.3, 2.7), dpi=100)
        canvas = canvas_class(fig)
        ax = fig.add_axes([0.17, 0.2, 0.5, 0.6])
        ax.plot(
            [1e-9, 1.0], [3e-12, 2.0], label="director rattle, mujoco RK4\n(diverged at 1.64 s)"
        )
        ax.set_yscale("log")
        ax.set_ylabel("attitude error [rad]")
        ax.set_title("cone_top: errors 10⁻⁵ ✓ ✗ ↯", fontsize=10.5)
        ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), frameon=False)
        for k in range(7):
            fig.text(0.013 + 0.0371 * k, 0.0137 * k + 0.003, f"t = {k}.37 s", fontsize=7 + 0.7 * k,
                     weight="bold" if k % 2 else "normal")  # fmt: skip
        fig.text(0.5, 0.9, r"$\omega_3 = 10^{-5}$ dt")
        canvas.draw()
        return np.asarray(canvas.buffer_rgba()).copy()

    assert agg_text.SUPPORTED, f"matplotlib {matplotlib.__version__}: plain Agg is drawn"
    agg_text._GLYPHS.clear(), agg_text._LAYOUTS.clear(), agg_text._METRICS.clear()
    want = draw(FigureCanvasAgg)
    first = draw(agg_text.FigureCanvasCachedText)
    assert agg_text._GLYPHS and agg_text._LAYOUTS and agg_text._METRICS  # it did cache
    second = draw(agg_text.FigureCanvasCachedText)
    assert want.shape == first.shape == second.shape
    assert (want != first).any(axis=-1).sum() == 0
    assert (want != second).any(axis=-1).sum() == 0


def test_a_cropped_png_has_the_pixels_savefig_writes(tmp_path):
    """canvas._write_png with ``bbox_inches`` (the scorecard picture) takes savefig's pixels
    as written (canvas._Pixels) instead of a full-colour PNG: the same size and pixels as
    savefig's own PNG of the same crop, quantized the same way, for a box reaching beyond
    the figure and for one inside it."""
    import numpy as np
    from matplotlib.transforms import Bbox
    from PIL import Image

    from reports.report import canvas

    plt = canvas._plt()
    for box in (None, Bbox([[0.31, 0.27], [2.63, 1.91]])):
        fig = plt.figure(figsize=(3.1, 2.2), dpi=canvas.DPI)
        ax = fig.add_axes([0.2, 0.2, 0.6, 0.6])
        ax.plot([0, 1], [0, 1], label="a line")
        ax.text(-0.4, 1.3, "text beyond the figure's edge", fontsize=9)
        ax.set_title("title")
        crop = fig.get_tightbbox().padded(0.1) if box is None else box
        got, want = tmp_path / "got.png", tmp_path / "want.png"
        canvas._write_png(fig, got, bbox_inches=crop)
        fig.savefig(want, format="png", dpi=canvas.DPI, bbox_inches=crop)
        plt.close(fig)
        with Image.open(want) as im:
            ref = im.convert("RGB").quantize(colors=256, method=Image.Quantize.FASTOCTREE)
            ref_rgb = np.asarray(ref.convert("RGB"))
        with Image.open(got) as im:
            assert im.size == ref.size
            assert np.array_equal(np.asarray(im.convert("RGB")), ref_rgb)
            assert im.size != (310, 220)  # cropped: not the figure's own size
