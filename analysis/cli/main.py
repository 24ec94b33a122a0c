"""Command line (or ``motion-analysis``):

    python -m analysis report RATINGS.csv --out report/ [--rules RULES.json] [--motion DIR ...]
                              [--previous OLD_RATINGS.csv --previous-rules OLD_RULES.json]
    python -m analysis objective DIR ... --out objective/ [--appropriateness RATINGS.csv]
    python -m analysis hvrnn-scores OUTPUTS.npz --out scores/
    python -m analysis leaderboard RATINGS.csv --out leaderboard/   (and the other commands
        of `analysis.cli.rankings`)
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

import pandas as pd

from analysis.reports import plots
from analysis.reports.adherence import adherence_correlation, label_adherence, path_adherence
from analysis.stats.matching import appropriateness_pages
from analysis.reports.attribute_scores import read_classifier_outputs, write_scores
from analysis.cli.options import add_exclusion_arguments, exclusion_rules
from analysis.designs import design_of
from analysis.errors import AnalysisInputError
from analysis.ratings.exclusions import ExclusionRules, apply_exclusions
from analysis.motion.motion_io import SystemClips, load_motion_sets
from analysis.motion.objective import objective_metrics
from analysis.cli.rankings import add_commands as add_ranking_commands
from analysis.ratings.previous_run import previous_run_comparison
from analysis.ratings.schema import read_ratings
from analysis.reports.single_report import write_report
from analysis.ratings.report import build_report, require_design_taking_motion
from analysis.reports.tables import objective_table, to_markdown, write_table
from analysis.motion.centimetres import to_centimetres_y_up
from measures.units import parse_scale


def parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="motion-analysis",
        description="Significance tables and objective metrics for motion rating studies "
                    "(MoGlow / HVRNN protocols).")
    commands = parser.add_subparsers(dest="command", required=True)
    report = commands.add_parser(
        "report", help="turn a ratings CSV (and optionally motion) into a report folder",
        description="Read a ratings CSV (schema: docs/ratings-schema.md), apply the "
                    "exclusion rules, run ANOVA, Tukey HSD and a mixed model per task and "
                    "control class, and write tables (CSV, Markdown, LaTeX, JSON), figures "
                    "(PNG, SVG) and summary.md. With --motion, add the objective metrics. "
                    "Side-by-side tables (design column) get Wilcoxon signed-rank tests with "
                    "Holm correction, pairwise tables sign tests and a Bradley-Terry scale, "
                    "appropriateness tables the share preferring the matched clip, the mean "
                    "appropriateness score and tests between systems; every design but "
                    "appropriateness gets the ratings needed for 80 % power per pair.")
    report.add_argument("ratings", help="ratings CSV file")
    report.add_argument("--out", required=True, help="folder to write the report into")
    report.add_argument("--reference", help="system to mark significant differences from "
                                            "(default: NAT when rated)")
    report.add_argument("--motion", nargs="+", default=[], metavar="DIR_OR_NPZ",
                        help="motion clips as .npz files or folders of them (layout: "
                             "analysis/motion/motion_io.py); a subfolder or file stem names the system")
    report.add_argument("--systems", help="comma-separated list of expected systems; any other "
                                          "system in the ratings is an error")
    add_exclusion_arguments(report)
    report.add_argument("--continuity-correction", action="store_true",
                        help="correct the normal approximation of the side-by-side and appropriateness Wilcoxon tests by "
                             "half a unit, as R's wilcox.test does (default: no correction, as scipy)")
    report.add_argument("--foot-joints", help="comma-separated foot joint names (default: "
                                              "found by name)")
    report.add_argument("--foot-kind", choices=("heel", "toe"), default="heel",
                        help="heel for bipeds (default), toe for quadrupeds")
    report.add_argument("--previous", metavar="RATINGS.csv",
                        help="the ratings of a previous run of the study (a rerun with more systems): each run's "
                             "kept ratings per system, side by side, in tables/previous_run")
    report.add_argument("--previous-rules", metavar="RULES.json",
                        help="the rules the previous run was collected under (default: this run's)")
    _add_unit_arguments(report)
    _add_objective_parser(commands)
    scores = commands.add_parser(
        "hvrnn-scores", help="IS and FID per set and t-SNE maps (HVRNN Table 2, Fig. 4)",
        description="Read the attribute-classifier outputs written by 'python -m generation hvrnn-eval'; "
                    "write the IS/FID table and a t-SNE figure per classifier.")
    scores.add_argument("outputs", help="classifier outputs (.npz)")
    scores.add_argument("--out", required=True, help="folder to write tables and figures into")
    add_ranking_commands(commands)
    return parser


def _add_objective_parser(commands) -> None:
    objective = commands.add_parser(
        "objective", help="objective metrics of motion alone (no ratings): Table 3 and Fig. 5, control adherence",
        description="Footstep and bone-length metrics of each system's clips, the MoGlow Table 3 layout "
                    "(value closest to the natural system marked) and the footstep curves. Clips that carry "
                    "the path they were asked to follow (as `python -m generation sample` and `natural` write "
                    "them) also get their control adherence: the root's distance from the path (cm) and its "
                    "heading error (degrees), over time and at the end; label models get the attribute "
                    "classifiers' accuracy (--classifier-outputs). With --appropriateness, how each "
                    "adherence metric correlates with the systems' mean appropriateness scores.")
    objective.add_argument("motion", nargs="+", metavar="DIR_OR_NPZ",
                           help="motion clips (layout: analysis/motion/motion_io.py); a subfolder or file stem names the system")
    objective.add_argument("--out", required=True, help="folder to write tables and the figure into")
    objective.add_argument("--natural", default="NAT", help="name of the natural-motion system")
    objective.add_argument("--foot-joints", help="comma-separated foot joint names (default: found by name)")
    objective.add_argument("--foot-kind", choices=("heel", "toe"), default="heel")
    objective.add_argument("--classifier-outputs", metavar="OUTPUTS.npz",
                           help="attribute-classifier outputs of label-controlled systems (python -m generation "
                                "hvrnn-eval): how often the action and style asked for are recognised, per set")
    objective.add_argument("--appropriateness", metavar="RATINGS.csv",
                           help="an appropriateness ratings table of the same systems: correlate each system's mean "
                                "appropriateness score (after the exclusions) with its control adherence")
    objective.add_argument("--attention", default="BAD", help="name of the attention-check system of the ratings")
    _add_unit_arguments(objective)


def _scale(text: str) -> float | None:
    try:
        return parse_scale(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def _add_unit_arguments(parser: argparse.ArgumentParser) -> None:
    """The motion's unit and up axis, the same options for every command that reads motion."""
    group = parser.add_argument_group("units (the motion is read into cm, y up)")
    group.add_argument("--scale", type=_scale, default="auto", metavar="auto|UNIT|NUMBER",
                       help="the motion's length unit: auto (from the figures' height; clips in different units "
                            "are an error naming them), a unit (mm, cm, in, cmu, ft, m) or centimetres per unit "
                            "(default %(default)s)")
    group.add_argument("--up", choices=("auto", "y", "z"), default="auto",
                       help="the motion's up axis (default %(default)s: the one the figures stand along)")


def _motion_in_centimetres(args: argparse.Namespace) -> dict[str, SystemClips]:
    """The --motion clips in cm with y up; prints what they were taken to be."""
    motion, units = to_centimetres_y_up(load_motion_sets(args.motion), args.scale,
                                        None if args.up == "auto" else args.up)
    print(units)
    return motion


@contextmanager
def staged_output(out: Path) -> Iterator[Path]:
    """A temporary folder beside ``out`` whose files move into ``out`` when the block ends
    without an error; a failure (bad input, an unwritable figure) leaves ``out`` as it was."""
    if out.exists() and not out.is_dir():
        raise AnalysisInputError(f"--out {out} is a file; name a folder to write into")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        work = Path(tempfile.mkdtemp(dir=out.parent, prefix=f".{out.name}.building-"))
    except OSError as exc:
        raise AnalysisInputError(f"cannot write into {out}: {exc.strerror}") from None
    try:
        yield work
        for file in sorted(work.rglob("*")):
            if file.is_file():
                target = out / file.relative_to(work)
                target.parent.mkdir(parents=True, exist_ok=True)
                os.replace(file, target)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def objective_command(args: argparse.Namespace, out: Path) -> list[str]:
    """Write the objective tables and figures into ``out``; returns the notes."""
    motion = _motion_in_centimetres(args)
    table, curves, notes = objective_metrics(motion, _split(args.foot_joints), args.foot_kind)
    write_table(table, out / "tables", "objective_metrics")
    write_table(objective_table(table, args.natural), out / "tables", "table3_objective",
                caption=f"Objective metrics (MoGlow Table 3 layout); marked: closest to {args.natural}.")
    write_table(curves, out / "tables", "footstep_curves", formats=("csv", "json"))
    plots.save_figure(plots.footstep_plot(curves, args.natural), out / "figures", "footstep_curves")
    print(to_markdown(objective_table(table, args.natural)))
    adherence = _adherence(args, motion, out, notes)
    if args.appropriateness:
        if adherence.empty:
            raise AnalysisInputError("--appropriateness correlates scores with control adherence, and no clip "
                                     "carries a control path nor were --classifier-outputs given")
        correlation, correlation_notes = adherence_correlation(_mean_scores(args), adherence)
        notes += correlation_notes
        write_table(correlation, out / "tables", "adherence_correlation",
                    caption="Pearson correlation across systems of the mean appropriateness score with "
                            "each control-adherence metric.")
        print(to_markdown(correlation.round(3)))
    return notes


def _adherence(args: argparse.Namespace, motion: dict[str, SystemClips], out: Path,
               notes: list[str]) -> pd.DataFrame:
    """Write the control-adherence tables and figure; the metrics of every system, one row each."""
    paths, over_time, path_notes = path_adherence(motion)
    notes += path_notes
    if len(paths):
        write_table(paths, out / "tables", "control_adherence",
                    caption="Control adherence of path-controlled systems: the root's distance from the "
                            "control's path (cm) and its heading error (degrees), mean over time and at the end.")
        write_table(over_time, out / "tables", "adherence_over_time", formats=("csv", "json"))
        plots.save_figure(plots.adherence_plot(over_time, args.natural), out / "figures", "adherence_over_time")
        print(to_markdown(paths.round(2)))
    labels = pd.DataFrame()
    if args.classifier_outputs:
        labels = label_adherence(read_classifier_outputs(args.classifier_outputs))
        write_table(labels, out / "tables", "label_adherence",
                    caption="Share of sequences whose action and style the attribute classifiers recognise "
                            "(Wilson 95 % intervals).")
        print(to_markdown(labels.round(3)))
    measured = [frame for frame in (paths, labels) if len(frame)]
    return pd.concat(measured, ignore_index=True) if measured else pd.DataFrame(columns=["system"])


def _mean_scores(args: argparse.Namespace) -> pd.Series:
    """Each system's mean appropriateness score over the kept pages of --appropriateness."""
    ratings = read_ratings(args.appropriateness)
    design = design_of(ratings)
    if not design.judges_appropriateness:
        raise AnalysisInputError(f"--appropriateness {args.appropriateness} is a {design.name} table; "
                                 "give an appropriateness table (docs/ratings-schema.md)")
    flagged = apply_exclusions(ratings, ExclusionRules(natural_system=args.natural, attention_system=args.attention))
    kept = flagged[flagged["kept"] & (flagged["system"] != args.attention)]
    if kept.empty:
        raise AnalysisInputError(f"--appropriateness {args.appropriateness}: no pages are left after the exclusions")
    return appropriateness_pages(kept).groupby("system")["score"].mean()



def _previous_run(args: argparse.Namespace, ratings: pd.DataFrame, rules: ExclusionRules, out: Path) -> list[Path]:
    """The previous run's table beside this one's (``analysis.ratings.previous_run``)."""
    previous_rules = rules
    if args.previous_rules:
        try:
            text = Path(args.previous_rules).read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as error:
            raise AnalysisInputError(f"cannot read --previous-rules {args.previous_rules} ({error})") from None
        previous_rules = ExclusionRules.from_json(text, source=args.previous_rules)
    table = previous_run_comparison(ratings, rules, read_ratings(args.previous), previous_rules)
    return write_table(table, out / "tables", "previous_run",
                       caption="Each run's kept ratings per system: the previous run of the study and this one.")


def _split(text: str | None) -> list[str] | None:
    return [t.strip() for t in text.split(",") if t.strip()] if text else None


def main(argv: Sequence[str] | None = None) -> int:
    command_line = parser()
    args = command_line.parse_args(argv)
    if getattr(args, "previous_rules", None) and not args.previous:
        command_line.error("--previous-rules needs --previous (the previous run's ratings)")
    try:
        return _run(args)
    except AnalysisInputError as exc:
        print(f"motion-analysis: error: {exc}", file=sys.stderr)
        return 2


def _run(args: argparse.Namespace) -> int:
    out = Path(args.out)
    if hasattr(args, "write"):  # the commands of analysis.cli.rankings
        with staged_output(out) as work:
            lines = args.write(args, work)
        print("\n".join(lines))
        return 0
    if args.command == "hvrnn-scores":
        with staged_output(out) as work:
            table = write_scores(args.outputs, work)
        print(to_markdown(table.round(3)))
        return 0
    if args.command == "objective":
        with staged_output(out) as work:
            notes = objective_command(args, work)
        for note in notes:
            print(f"note: {note}")
        return 0
    rules = exclusion_rules(args)
    with staged_output(out) as work:
        ratings = read_ratings(args.ratings)
        if args.motion:
            require_design_taking_motion(ratings)  # before the motion is read: the ratings decide whether it is used
        motion = _motion_in_centimetres(args) if args.motion else None
        report = build_report(ratings, motion, reference=args.reference, rules=rules,
                              systems=_split(args.systems),
                              compare_attention_checks=args.compare_attention_checks,
                              continuity_correction=args.continuity_correction,
                              foot_joints=_split(args.foot_joints), foot_kind=args.foot_kind)
        written = [out / path.relative_to(work) for path in write_report(report, work)]
        if args.previous:
            written += [out / path.relative_to(work) for path in _previous_run(args, ratings, rules, work)]
    print(f"wrote {len(written)} files to {out} (summary: {written[0]})")
    for note in report.notes:
        print(f"note: {note}")
    return 0
