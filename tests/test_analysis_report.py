"""The report folder end to end, through the command line, and how bad input is handled."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from analysis import AnalysisInputError, build_report, validate_ratings, write_report
from analysis.cli import main
from analysis.motion.motion_io import load_motion_sets, save_clips
from analysis.ratings.simulate import simulate_ratings
from analysis.reports.tables import to_latex

pytestmark = pytest.mark.slow

SYSTEMS = {"NAT": 4.2, "MoGlow": 3.9, "LSTM": 2.9, "VAE": 3.3}


@pytest.fixture(scope="module")
def ratings() -> pd.DataFrame:
    return simulate_ratings(SYSTEMS, 6000, tasks=("human", "dog"), seed=5)


@pytest.fixture(scope="module")
def ratings_file(ratings, tmp_path_factory):
    path = tmp_path_factory.mktemp("ratings") / "ratings.csv"
    ratings.to_csv(path, index=False)
    return path


@pytest.fixture(scope="module")
def motion_dir(tmp_path_factory, motion_data):
    from generation.motion import load_motion

    walks = [load_motion(p) for p in sorted((motion_data / "data").glob("dataset-1_walk_*_001.bvh"))[:6]]
    skeleton = walks[0].skeleton
    folder = tmp_path_factory.mktemp("motion")
    rng = np.random.default_rng(0)
    for i, walk in enumerate(walks):
        for system, noise in (("NAT", 0.0), ("MoGlow", 0.3), ("LSTM", 3.0), ("VAE", 1.0)):
            (folder / system).mkdir(exist_ok=True)
            positions = walk.positions + rng.normal(0, noise, walk.positions.shape)
            save_clips(folder / system / f"clip{i}.npz", positions, walk.fps, skeleton.names,
                       skeleton.parents, skeleton.offsets)
    return folder


def test_cli_writes_every_table_format_figure_and_summary(ratings_file, motion_dir, tmp_path, capsys):
    out = tmp_path / "report"
    assert main(["report", str(ratings_file), "--out", str(out), "--motion", str(motion_dir)]) == 0
    tables = out / "tables"
    for name in ("table2_significance", "table3_objective", "anova", "tukey_hsd", "system_means",
                 "mixed_model_means", "exclusions", "pvalues_human_held-out", "correlation"):
        for ext in ("csv", "md", "tex", "json"):
            assert (tables / f"{name}.{ext}").is_file(), f"{name}.{ext}"
    for name in ("means_ci", "rating_distributions", "footstep_curves"):
        for ext in ("png", "svg"):
            assert (out / "figures" / f"{name}.{ext}").stat().st_size > 1000
    summary = (out / "summary.md").read_text()
    assert "participants" in summary and "Tukey HSD" in summary and "F(3, " in summary
    table2 = pd.read_csv(tables / "table2_significance.csv")
    assert table2["system"].tolist() == ["NAT", "LSTM", "MoGlow", "VAE"]
    assert table2.columns.tolist()[1:] == ["dog · held-out", "dog · synthetic",
                                           "human · held-out", "human · synthetic"]
    assert table2.iloc[1, 1].endswith("**")  # LSTM is far below NAT
    assert not table2.isna().any().any()
    table3 = pd.read_csv(tables / "table3_objective.csv").set_index("system")
    assert table3.loc["MoGlow", "bone_length_rmse"].endswith("†")  # least noise is closest to NAT
    assert float(table3.loc["NAT", "bone_length_rmse"]) < 0.01
    records = json.loads((tables / "anova.json").read_text())
    assert {r["task"] for r in records} == {"human", "dog"}
    assert "wrote" in capsys.readouterr().out


def test_help_describes_the_report_command(capsys):
    with pytest.raises(SystemExit) as stop:
        main(["report", "--help"])
    assert stop.value.code == 0
    assert "--reference" in capsys.readouterr().out


@pytest.mark.parametrize("command", ["report", "objective", "hvrnn-scores", "leaderboard",
                                     "simulate-pairing", "rater-models"])
def test_every_help_prints_percent_signs_once(command, capsys):
    # argparse collapses "%%" in an option's help, not in a description without %(prog)s
    with pytest.raises(SystemExit) as stop:
        main([command, "--help"])
    text = capsys.readouterr().out
    assert stop.value.code == 0 and "%%" not in text


def test_previous_rules_without_the_previous_ratings_is_refused_not_ignored(capsys, tmp_path):
    with pytest.raises(SystemExit) as stop:
        main(["report", "ratings.csv", "--previous-rules", "rules.json", "--out", str(tmp_path / "out")])
    assert stop.value.code == 2 and "--previous-rules needs --previous" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_missing_reference_system_is_a_clear_error(ratings):
    with pytest.raises(AnalysisInputError, match="reference system 'GAN' does not exist"):
        build_report(validate_ratings(ratings), reference="GAN")


def test_cli_reports_bad_input_without_a_traceback(tmp_path, capsys):
    path = tmp_path / "bad.csv"
    path.write_text("participant,system,stimulus,value\np1,A,s1,3\n")
    assert main(["report", str(path), "--out", str(tmp_path / "out")]) == 2
    assert "scale_min, scale_max" in capsys.readouterr().err


def test_unknown_systems_are_rejected_when_the_expected_systems_are_given(ratings):
    with pytest.raises(AnalysisInputError, match="unknown system.*VAE"):
        build_report(validate_ratings(ratings), systems=["NAT", "MoGlow", "LSTM"])


def test_a_system_with_one_rating_is_noted_and_shown_not_as_nan(ratings):
    lonely = pd.DataFrame([{**ratings.iloc[0].to_dict(), "system": "Solo", "stimulus": "solo_1",
                            "task": "human", "control_class": "held-out", "value": 3,
                            "played_until_s": 10.0}])
    report = build_report(validate_ratings(pd.concat([ratings, lonely], ignore_index=True)))
    assert any("Solo in human · held-out: only 1 kept rating" in n for n in report.notes)
    cell = report.significance_display.loc["Solo", ("human", "held-out")]
    assert cell == "n=1, not computed"
    assert report.significance_display.loc["Solo", ("dog", "held-out")] == "-"
    assert "Solo" not in set(report.tukey["system_a"]) | set(report.tukey["system_b"])


def test_a_system_rated_once_stands_in_the_means_plot_without_an_interval_as_in_the_distributions(ratings):
    from analysis.reports.single_report import report_figures
    lonely = pd.DataFrame([{**ratings.iloc[0].to_dict(), "system": "Solo", "stimulus": "solo_1",
                            "task": "human", "control_class": "held-out", "value": 3,
                            "played_until_s": 10.0}])
    report = build_report(validate_ratings(pd.concat([ratings, lonely], ignore_index=True)))
    figures = report_figures(report)
    for name in ("means_ci", "rating_distributions"):
        labels = [tick.get_text() for tick in figures[name].axes[0].get_yticklabels()]
        assert "Solo" in labels, (name, labels)
    means = figures["means_ci"]
    row = [t.get_text() for t in means.axes[0].get_yticklabels()].index("Solo")
    at = means.axes[0].get_yticks()[row]
    panel = next(ax for ax in means.axes if ax.get_title() == "human · held-out")
    hollow = [line for line in panel.get_lines() if line.get_markerfacecolor() == "none"]
    assert [(list(line.get_xdata()), list(line.get_ydata())) for line in hollow] == [([3.0], [at])]
    assert [t.get_text() for t in panel.get_legend().get_texts()] == ["one rating: no interval"]


def test_no_natural_system_means_no_markers_and_a_note(ratings):
    report = build_report(validate_ratings(ratings[ratings["system"] != "NAT"]))
    assert report.reference is None
    assert any("No reference system" in n for n in report.notes)
    assert not any("*" in cell for cell in report.significance_display.to_numpy().ravel())


def test_a_reference_not_rated_in_one_column_is_noted(ratings):
    data = ratings[~((ratings["system"] == "NAT") & (ratings["task"] == "dog"))]
    report = build_report(validate_ratings(data))
    assert any("NAT was not rated in dog" in n for n in report.notes)
    assert report.significance_display.loc["NAT", ("dog", "held-out")] == "-"


def test_missing_timings_are_noted(ratings):
    report = build_report(validate_ratings(ratings.drop(columns=["played_until_s"])))
    assert any("early-answer rule was not applied" in n for n in report.notes)


def test_write_report_returns_the_files_and_notes_land_in_the_summary(ratings, tmp_path):
    report = build_report(validate_ratings(ratings.drop(columns=["played_until_s"])))
    written = write_report(report, tmp_path)
    assert all(p.exists() for p in written)
    assert "early-answer rule was not applied" in (tmp_path / "summary.md").read_text()


def test_motion_folders_name_systems_and_reject_broken_files(tmp_path):
    save_clips(tmp_path / "A.npz", np.zeros((2, 5, 3, 3)), 20, ["a", "b", "c"], [-1, 0, 1])
    (tmp_path / "B").mkdir()
    save_clips(tmp_path / "B" / "x.npz", np.zeros((5, 3, 3)), 20, ["a", "b", "c"], [-1, 0, 1],
               system="Named")
    systems = load_motion_sets([tmp_path])
    assert sorted(systems) == ["A", "Named"] and len(systems["A"].clips) == 2
    np.savez(tmp_path / "broken.npz", positions=np.zeros((5, 3, 3)))
    with pytest.raises(AnalysisInputError, match="lacks fps, names, parents"):
        load_motion_sets([tmp_path / "broken.npz"])


def test_latex_tables_use_booktabs_and_escape_text():
    table = pd.DataFrame({"a_b": ["4.17±0.11**", "50%"]}, index=pd.Index(["NAT", "x&y"], name="system"))
    tex = to_latex(table)
    assert r"\toprule" in tex and r"\midrule" in tex and r"\bottomrule" in tex
    assert r"4.17$\pm$0.11$^{**}$" in tex and r"x\&y" in tex and r"50\%" in tex and r"a\_b" in tex


def test_motion_in_metres_or_z_up_gives_the_report_of_the_motion_in_centimetres(ratings_file, clip_path, tmp_path,
                                                                                  capsys):
    from generation.motion import load_motion
    from measures.units import Z_UP_TO_Y_UP
    from tests.rig_variants import write_variants

    walks = dict(zip(SYSTEMS, ("walk_normal_001", "walk_happy_001", "walk_old_001", "walk_angry_001")))
    noise_cm = {"NAT": 0.0, "MoGlow": 0.3, "LSTM": 3.0, "VAE": 1.0}  # bone-length errors that differ
    # A vector in cm, y up, as each variant's file has it.
    as_written = {"cm": lambda v: v, "metres": lambda v: v / 100, "z-up": lambda v: v @ Z_UP_TO_Y_UP}
    rng = np.random.default_rng(0)
    for system, walk in walks.items():
        source = clip_path(walk)
        files = {"cm": source, **write_variants(source, tmp_path / "rigs" / walk)}
        noise = rng.normal(0, noise_cm[system], load_motion(source).positions.shape)
        for variant, convert in as_written.items():
            raw = load_motion(files[variant])  # as the file has it: no unit or axis conversion
            (tmp_path / variant / system).mkdir(parents=True)
            save_clips(tmp_path / variant / system / "clip.npz", raw.positions + convert(noise), raw.fps,
                       raw.skeleton.names, raw.skeleton.parents, raw.skeleton.offsets)
    said = {}
    for variant in ("cm", "metres", "z-up"):
        assert main(["report", str(ratings_file), "--out", str(tmp_path / f"report-{variant}"),
                     "--motion", str(tmp_path / variant)]) == 0
        said[variant] = capsys.readouterr().out
    assert "motion units: cm, y up (scale detected, up axis detected)" in said["cm"]
    assert "motion units: m, y up (scale detected" in said["metres"]
    assert "motion units: cm, z up (scale detected" in said["z-up"]
    tables = sorted(p.name for p in (tmp_path / "report-cm" / "tables").glob("*.csv"))
    assert {"table3_objective.csv", "objective_metrics.csv", "correlation.csv"} <= set(tables)
    for variant in ("metres", "z-up"):
        for name in tables:
            expected = pd.read_csv(tmp_path / "report-cm" / "tables" / name)
            pd.testing.assert_frame_equal(pd.read_csv(tmp_path / f"report-{variant}" / "tables" / name), expected,
                                          rtol=1e-4, atol=1e-4, obj=f"{variant}: {name}")
    # Given, the unit is used as it is: metres read as metres give the same again.
    assert main(["report", str(ratings_file), "--out", str(tmp_path / "given"), "--motion", str(tmp_path / "metres"),
                 "--scale", "m", "--up", "y"]) == 0
    assert "motion units: m, y up (scale given, up axis given)" in capsys.readouterr().out
    pd.testing.assert_frame_equal(pd.read_csv(tmp_path / "given" / "tables" / "objective_metrics.csv"),
                                  pd.read_csv(tmp_path / "report-cm" / "tables" / "objective_metrics.csv"),
                                  rtol=1e-4, atol=1e-4)


def test_motion_mixing_units_is_refused_naming_the_clips_in_the_other_unit(ratings_file, motion_dir, tmp_path,
                                                                             capsys):
    import shutil

    folder = tmp_path / "motion"
    shutil.copytree(motion_dir, folder)
    with np.load(folder / "MoGlow" / "clip0.npz") as clip:
        arrays = dict(clip)
    save_clips(folder / "MoGlow" / "clip0.npz", arrays["positions"] / 100, float(arrays["fps"]), arrays["names"],
               arrays["parents"], arrays["offsets"] / 100)
    out = tmp_path / "report"
    assert main(["report", str(ratings_file), "--out", str(out), "--motion", str(folder)]) == 2
    err = capsys.readouterr().err
    assert "the clips mix units: 23 are in cm (such as" in err
    assert f"but not {folder / 'MoGlow' / 'clip0.npz'} (1." in err and "units: m); convert them, or give --scale" in err
    assert not out.exists()
    assert main(["report", str(ratings_file), "--out", str(out), "--motion", str(folder), "--scale", "cm"]) == 0
