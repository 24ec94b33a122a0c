"""Hostile ratings tables: each gets a clear error naming the problem, and leaves nothing.

The same table goes to the command line (``python -m analysis report``: exit status 2,
a message on stderr, no output folder) and to the web upload (400, the message on the
form, no report folder). Labels that are legal but hostile to an output format (LaTeX,
Markdown, spreadsheets, matplotlib's TeX) come out escaped.
"""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from django.contrib.auth.models import User

from analysis.cli import main
from analysis.ratings.simulate import simulate_pairwise, simulate_ratings, simulate_side_by_side
from analysis.reports.tables import spreadsheet_safe, to_latex, to_markdown, write_table

GOOD = simulate_ratings({"NAT": 4.2, "MoGlow": 3.8, "RNN": 2.9}, 600, seed=3).to_csv(index=False)
HEADER, FIRST, *REST = GOOD.splitlines()


def _with_first_row(row: str) -> bytes:
    return "\n".join([HEADER, row, *REST]).encode() + b"\n"


HOSTILE_TABLES = {
    "latin-1 text": (GOOD.replace("MoGlow", "MoGlöw").encode("latin-1"), "not UTF-8 text (byte"),
    "binary junk": (b"\xff\xfe\x00\x01" * 50, "not UTF-8 text"),
    "a ragged row": ("\n".join([HEADER, FIRST, *REST[:3], REST[3] + ",extra,cells", *REST[4:]]).encode(),
                     "Expected 10 fields in line 6, saw 12"),
    "-inf scale": (_with_first_row(FIRST.replace(",1,5,", ",-inf,5,")), "'scale_min' must hold integers"),
    "1e20 scale": (GOOD.replace(",1,5,", ",1,1e20,").encode(), "between -1,000,000 and 1,000,000"),
    "nan value": (_with_first_row(FIRST.replace(",1,5,", ",1,5,").rsplit(",", 5)[0] + ",nan,1,5,10.0,10.0"),
                  "'value' must hold integers"),
    "infinite timing": (_with_first_row(FIRST.rsplit(",", 1)[0] + ",inf"), "'played_until_s' must hold finite"),
    "a duplicated row": ((GOOD + FIRST + "\n").encode(), f"row {len(REST) + 2} repeats row 1 exactly"),
    "no rows": ((HEADER + "\n").encode(), "has no rows"),
    "no rows of a pairwise table": (b"design,participant,system,stimulus,page,side,answer\n", "has no rows"),
    "empty file": (b"", "is empty"),
    "no required columns": (b"a,b\n1,2\n", "lacks the required column"),
}


@pytest.mark.parametrize("data, message", HOSTILE_TABLES.values(), ids=HOSTILE_TABLES.keys())
def test_hostile_ratings_on_the_command_line_exit_2_naming_the_problem(data, message, tmp_path, capsys):
    ratings = tmp_path / "ratings.csv"
    ratings.write_bytes(data)

    assert main(["report", str(ratings), "--out", str(tmp_path / "out")]) == 2

    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert str(ratings) in err or "row" in err or "column" in err  # where the fault is
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ratings.csv"]  # no report, no staging folder


def test_a_folder_as_the_ratings_file_is_refused_by_name(tmp_path, capsys):
    assert main(["report", str(tmp_path), "--out", str(tmp_path / "out")]) == 2
    assert f"{tmp_path} is a folder" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_out_naming_a_file_is_refused_and_the_file_kept(tmp_path, capsys):
    (tmp_path / "ratings.csv").write_text(GOOD)
    (tmp_path / "taken").write_text("mine")
    assert main(["report", str(tmp_path / "ratings.csv"), "--out", str(tmp_path / "taken")]) == 2
    assert f"--out {tmp_path / 'taken'} is a file" in capsys.readouterr().err
    assert (tmp_path / "taken").read_text() == "mine"


HOSTILE_NAMES = ["$\\undefinedmacro{$", "GAN*", "<script>alert(1)</script>", "two\nlines", "=cmd|' /C calc'!A0",
                 "@SUM(1+1)", "+1+1", "-2+3", "a|pipe"]


def test_a_report_on_systems_with_hostile_names_is_written_whole_and_escaped(tmp_path, capsys):
    table = simulate_ratings({"NAT": 4.2, **{name: 3.0 + i / 10 for i, name in enumerate(HOSTILE_NAMES)}}, 4000,
                             seed=4)
    ratings = tmp_path / "ratings.csv"
    table.to_csv(ratings, index=False)

    assert main(["report", str(ratings), "--out", str(tmp_path / "out")]) == 0, capsys.readouterr().err

    tables = tmp_path / "out" / "tables"
    assert (tmp_path / "out" / "figures" / "means_ci.svg").is_file()
    latex = (tables / "table2_significance.tex").read_text()
    assert r"\$\textbackslash{}undefinedmacro\{\$" in latex
    assert "GAN*" in latex and "GAN$^{*}$" not in latex  # a name's star is no significance mark
    markdown = (tables / "table2_significance.md").read_text()
    assert "<script>" not in markdown and "&lt;script&gt;" in markdown
    assert "two lines" in markdown and all(line.startswith("|") for line in markdown.splitlines()[2:])
    means = pd.read_csv(tables / "system_means.csv", keep_default_na=False)
    systems = set(means["system"])
    assert {"'=cmd|' /C calc'!A0", "'@SUM(1+1)", "'+1+1", "'-2+3"} <= systems
    assert not any(name.startswith(("=", "+", "-", "@")) for name in systems)


@pytest.mark.parametrize("value, safe", [("=1+2", "'=1+2"), ("-2+3", "'-2+3"), ("@A1", "'@A1"), ("\r=x", "'\r=x"),
                                         ("-1.5", "-1.5"), ("-", "-"), ("NAT", "NAT"), (3, 3)])
def test_spreadsheet_safe_prefixes_only_text_that_would_run_as_a_formula(value, safe):
    assert spreadsheet_safe(value) == safe


def test_tables_escape_labels_but_keep_their_own_marks(tmp_path):
    table = pd.DataFrame({"cell": ["3.80±0.12**", "1.00±0.20"]}, index=pd.Index(["NAT", "GAN**"], name="system"))
    latex = to_latex(table)
    assert r"3.80$\pm$0.12$^{**}$" in latex  # the significance cell keeps its superscript stars
    assert "GAN**" in latex and "GAN$^" not in latex
    markdown = to_markdown(table)
    assert r"GAN\*\*" in markdown
    written = write_table(table, tmp_path, "t", caption="<b>caption</b>\nsecond line")
    assert (tmp_path / "t.md").read_text().startswith("&lt;b&gt;caption&lt;/b&gt; second line\n")
    assert (tmp_path / "t.tex").read_text().startswith("% <b>caption</b> second line\n")
    assert json.loads((tmp_path / "t.json").read_text())[1]["system"] == "GAN**"
    assert len(written) == 4


@pytest.fixture
def researcher(client, settings, tmp_path):
    settings.MEDIA_ROOT = tmp_path
    user = User.objects.create_user("researcher", password="pw-for-tests")
    client.force_login(user)
    return user


@pytest.mark.django_db
@pytest.mark.parametrize("data, message", HOSTILE_TABLES.values(), ids=HOSTILE_TABLES.keys())
def test_hostile_ratings_uploaded_are_a_400_naming_the_problem(data, message, client, researcher, tmp_path):
    upload = io.BytesIO(data)
    upload.name = "ratings.csv"
    response = client.post("/analysis/", {"ratings": upload, "reference": "NAT"})

    assert response.status_code == 400
    page = response.content.decode()
    assert message.replace("'", "&#x27;") in page and "Traceback" not in page
    assert str(tmp_path) not in page  # the server's folders are not the researcher's business
    reports = Path(tmp_path) / "reports"
    assert not reports.exists() or list(reports.iterdir()) == []


def test_a_nan_exclusion_threshold_is_refused_rather_than_excluding_nobody(tmp_path, capsys):
    (tmp_path / "ratings.csv").write_text(GOOD)
    assert main(["report", str(tmp_path / "ratings.csv"), "--out", str(tmp_path / "out"), "--bad-threshold", "nan"]) == 2
    assert "bad_at_or_above must be a finite number" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


# One participant per design who fails its attention check, so no rating is left to analyse.
EVERYONE_EXCLUDED = {
    "single": "participant,system,stimulus,value,scale_min,scale_max\np1,BAD,b1,5,1,5\np1,A,a1,3,1,5\n",
    "side-by-side": "design,participant,system,stimulus,page,value,scale_min,scale_max\n"
                    "side-by-side,p1,BAD,b1,q1,90,0,100\nside-by-side,p1,A,a1,q1,50,0,100\n",
    "pairwise": "design,participant,system,stimulus,page,side,answer\n"
                "pairwise,p1,BAD,b1,q1,left,left\npairwise,p1,NAT,n1,q1,right,left\n",
    "appropriateness": "design,participant,system,stimulus,page,side,answer,matched\n"
                       "appropriateness,p1,BAD,b1m,q1,left,left,false\nappropriateness,p1,BAD,b1,q1,right,left,true\n",
}


@pytest.mark.parametrize("table", EVERYONE_EXCLUDED.values(), ids=EVERYONE_EXCLUDED.keys())
def test_a_table_whose_every_participant_is_excluded_exits_2_whatever_its_design(table, tmp_path, capsys):
    (tmp_path / "ratings.csv").write_text(table)
    assert main(["report", str(tmp_path / "ratings.csv"), "--out", str(tmp_path / "out")]) == 2
    assert "no ratings are left after the exclusions" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def _npz(**overrides) -> dict:
    arrays = {"positions": np.zeros((10, 3, 3)), "fps": 20.0, "names": np.array(["hips", "knee", "foot"]),
              "parents": np.array([-1, 0, 1])}
    return {**arrays, **overrides}


HOSTILE_MOTION = {
    "fps 0": (_npz(fps=0.0), "fps must be a positive number, got 0.0"),
    "fps nan": (_npz(fps=np.nan), "fps must be a positive number"),
    "text positions": (_npz(positions=np.array(["a"] * 90).reshape(10, 3, 3)), "of the wrong type"),
    "a parent after its child": (_npz(parents=np.array([-1, 2, 0])), "parents must give each"),
    "a parent out of range": (_npz(parents=np.array([-1, 0, 7])), "parents must give each"),
    "infinite positions": (_npz(positions=np.full((10, 3, 3), np.inf)), "NaN or infinity"),
}


@pytest.mark.parametrize("arrays, message", HOSTILE_MOTION.values(), ids=HOSTILE_MOTION.keys())
def test_hostile_motion_for_the_objective_metrics_exits_2_naming_the_file(arrays, message, tmp_path, capsys):
    clip = tmp_path / "GAN.npz"
    np.savez(clip, **arrays)
    assert main(["objective", str(clip), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert f"{clip}: " in err and message in err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("simulate", [
    lambda names: simulate_side_by_side({"NAT": 70.0, **{n: 40.0 + 5 * i for i, n in enumerate(names)}}, 30, seed=2),
    lambda names: simulate_pairwise({"NAT": 1.0, **{n: 0.2 * i for i, n in enumerate(names)}}, 30, seed=2),
], ids=["side-by-side", "pairwise"])
def test_reports_of_other_designs_draw_hostile_names_as_written(simulate, tmp_path, capsys):
    ratings = tmp_path / "ratings.csv"
    simulate(["$\\undefinedmacro{$", "GAN*", "=1+2"]).to_csv(ratings, index=False)
    assert main(["report", str(ratings), "--out", str(tmp_path / "out")]) == 0, capsys.readouterr().err
    assert list((tmp_path / "out" / "figures").glob("*.svg"))
