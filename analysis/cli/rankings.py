"""The ranking commands of ``python -m analysis`` (registered by `analysis.cli`):

    python -m analysis leaderboard RATINGS.csv --out DIR [--anchor NAT] [--model davidson]
    python -m analysis simulate-pairing --out DIR [--studies 200] [--workers 4]
    python -m analysis rater-models RATINGS.csv --out DIR [--reference NAT]
    python -m analysis genea-votes RATINGS.csv --out DIR

Each command writes into a folder that `analysis.cli` stages (a failure leaves the
folder as it was) and returns the lines to print.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from analysis.cli.options import add_exclusion_arguments, exclusion_rules
from analysis.designs import design_of, designs_where
from analysis.errors import AnalysisInputError
from analysis.ratings.exclusions import apply_exclusions, compared_ratings, exclusion_notes
from analysis.ratings.genea_files import CARRIED, genea_csv, genea_layout
from analysis.rankings.leaderboard import MODELS, RESAMPLES
from analysis.reports.leaderboard_report import build_leaderboard, leaderboard_text, origin_text, write_leaderboard
from analysis.rankings.pairing import EXPLORATION
from analysis.reports.pairing_simulation import (DEFAULT_ELO, DEFAULT_VOTES, Scenario, compare_pairings,
                                         write_pairing_simulation)
from analysis.reports.rater_models import build_rater_models, rater_models_text, write_rater_models
from analysis.ratings.schema import read_ratings
from analysis.reports.reasons import has_reasons, reason_counts, write_reasons
from analysis.reports.tables import to_markdown

if TYPE_CHECKING:
    from analysis.designs.base import RatingDesign

GENEA_VOTES = "votes_genea.csv"


def _count(minimum: int):
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be at least {minimum}, got {value}")
        return value
    return parse


def add_commands(commands) -> None:
    """Add the ranking commands to the ``python -m analysis`` subparsers."""
    board = commands.add_parser(
        "leaderboard", help="rank the systems of a pairwise study on an Elo scale",
        description="Read a pairwise ratings CSV (docs/ratings-schema.md), apply the exclusion "
                    "rules, and rank the systems per task and control class with a weighted "
                    "Bradley-Terry model (GENEA leaderboard weights: a clear preference counts "
                    "4 wins, a slight one 2, a plain left/right answer 4, 'no preference' 1 "
                    "for each side) or Davidson's tie model, on an Elo scale with 95 % "
                    "intervals from a seeded bootstrap over participants. Writes the "
                    "leaderboard, battle counts, win fractions and side-bias test as tables "
                    "(CSV, Markdown, LaTeX, JSON), the heat maps (PNG, SVG) and summary.md.")
    board.add_argument("ratings", help="pairwise ratings CSV file")
    board.add_argument("--out", required=True, help="folder to write the leaderboard into")
    board.add_argument("--anchor", help="system fixed at Elo 1000 (default: the natural "
                                        "system where compared, else the systems' mean)")
    board.add_argument("--model", choices=MODELS, default=MODELS[0],
                       help="bradley-terry (ties count one win for each side; default) or "
                            "davidson (ties an outcome of their own)")
    board.add_argument("--resamples", type=_count(1), default=RESAMPLES,
                       help="bootstrap resamples of the participants (default %(default)s)")
    board.add_argument("--seed", type=int, default=0, help="the bootstrap's seed (default 0)")
    add_exclusion_arguments(board, thresholds=False)
    board.set_defaults(write=leaderboard_command)
    genea = commands.add_parser(
        "genea-votes", help="write a pairwise or appropriateness table as the GENEA leaderboard's vote file",
        description="Read a pairwise or appropriateness ratings CSV, or a GENEA battles or mismatch file "
                    "(analysis/ratings/genea_files.py), and write all its votes, exclusions not applied, as GENEA's "
                    "one-row-per-vote file DIR/votes_genea.csv; a GENEA file comes back byte for byte.")
    genea.add_argument("ratings", help="pairwise or appropriateness ratings CSV, or a GENEA vote file")
    genea.add_argument("--out", required=True, help="folder to write votes_genea.csv into")
    genea.set_defaults(write=genea_votes_command)
    simulate = commands.add_parser(
        "simulate-pairing", help="simulate pairwise studies with uniform and adaptive pairing",
        description="Simulate pairwise studies with five-level answers, pairs chosen uniformly "
                    "or adaptively (analysis.rankings.pairing), score each study's leaderboard at a "
                    "number of votes (Kendall's tau with the true order, mean 95 % interval "
                    "width, coverage of the true Elo), and write how many votes adaptive "
                    "pairing needs to match uniform pairing, with the best allocation's "
                    "saving as the ceiling. Seeded: the same options give the same tables.")
    simulate.add_argument("--out", required=True, help="folder to write tables, figure and summary into")
    simulate.add_argument("--elo", type=_elo, default=DEFAULT_ELO,
                          help="true Elo per system as NAME=ELO,... (the first is the anchor; "
                               "default: " + ",".join(f"{s}={v:g}" for s, v in DEFAULT_ELO.items()) + ")")
    simulate.add_argument("--studies", type=_count(1), default=200,
                          help="simulated studies per pairing (default %(default)s)")
    simulate.add_argument("--votes", type=_votes, default=DEFAULT_VOTES,
                          help="checkpoints, comma-separated numbers of votes (default "
                               + ",".join(map(str, DEFAULT_VOTES)) + ")")
    simulate.add_argument("--resamples", type=_count(1), default=1000,
                          help="bootstrap resamples per leaderboard (default %(default)s)")
    simulate.add_argument("--pages-per-participant", type=_count(1), default=20,
                          help="pages each simulated participant answers (default %(default)s)")
    simulate.add_argument("--exploration", type=_share, default=EXPLORATION,
                          help="share of adaptive pages drawn uniformly (default %(default)s)")
    simulate.add_argument("--seed", type=int, default=0, help="seed (default 0)")
    simulate.add_argument("--workers", type=_count(1), default=1,
                          help="processes to run studies in (default 1; the result does not depend on it)")
    simulate.set_defaults(write=simulate_pairing_command)
    models = commands.add_parser(
        "rater-models", help="crossed mixed models and rater agreement of single or side-by-side ratings",
        description="Read a single or side-by-side ratings CSV, apply the exclusion rules, and fit "
                    "per task and control class the linear mixed model value ~ system + "
                    "(1|participant) + (1|stimulus) by REML (system means, variance components, "
                    "contrasts against the reference with Holm), the cumulative link (logit) mixed "
                    "model by the Laplace approximation on Likert scales of up to 11 points "
                    "(thresholds, effects, random-effect standard deviations), and Krippendorff's "
                    "alpha. Writes the tables (CSV, Markdown, LaTeX, JSON) and summary.md.")
    models.add_argument("ratings", help="single or side-by-side ratings CSV file")
    models.add_argument("--out", required=True, help="folder to write the tables into")
    models.add_argument("--reference", help="system the contrasts are against (default: the natural "
                                            "system where rated, else the first in sorted order)")
    add_exclusion_arguments(models)
    models.set_defaults(write=rater_models_command)


def _elo(text: str) -> dict[str, float]:
    systems = {}
    for item in text.split(","):
        name, _, value = item.partition("=")
        try:
            systems[name.strip()] = float(value)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected NAME=ELO, got {item!r}") from None
        if not name.strip() or not np.isfinite(systems[name.strip()]):
            raise argparse.ArgumentTypeError(f"expected NAME=ELO with a finite ELO, got {item!r}")
    if len(systems) < 2:
        raise argparse.ArgumentTypeError("name at least two systems")
    return systems


def _votes(text: str) -> tuple[int, ...]:
    parse = _count(2)
    return tuple(sorted({parse(part.strip()) for part in text.split(",")}))


def _share(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number from 0 to 1, got {text!r}") from None
    if not 0.0 <= value <= 1.0:
        raise argparse.ArgumentTypeError(f"must lie in [0, 1], got {value}")
    return value


def _compared(args: argparse.Namespace, analysed: Callable[[RatingDesign], bool]) -> tuple[pd.DataFrame, list[str]]:
    """The ratings file's compared rows (kept, attention checks removed unless compared)
    and the exclusion notes; refuses a table of a design that is not ``analysed``."""
    ratings = read_ratings(args.ratings)
    design = design_of(ratings)
    if not analysed(design):
        raise AnalysisInputError(f"{args.command} analyses {' and '.join(designs_where(analysed))} tables; "
                                 f"{args.ratings} is {design.name}")
    rules = exclusion_rules(args)
    flagged = apply_exclusions(ratings, rules)
    kept = compared_ratings(flagged, rules)
    if kept.empty:
        raise AnalysisInputError("no ratings are left after the exclusions; nothing to analyse")
    return kept, exclusion_notes(flagged, rules)


def _summary(folder: Path, title: str, text: str, notes: list[str]) -> Path:
    listed = "".join(f"- {n}\n" for n in notes) or "- None: everything was computed.\n"
    path = folder / "summary.md"
    path.write_text(f"# {title}\n\n{text}\n\n## Notes (what was not computed, and why)\n\n{listed}",
                    encoding="utf-8")
    return path


def leaderboard_command(args: argparse.Namespace, out: Path) -> list[str]:
    kept, notes = _compared(args, lambda design: design.votes)
    report = build_leaderboard(kept, args.anchor, args.model, args.resamples, args.seed,
                               natural=exclusion_rules(args).natural_system)
    if report.board.empty:
        raise AnalysisInputError("no cell has a leaderboard: " + " ".join(report.notes))
    notes += report.notes
    written = write_leaderboard(report, out)
    if has_reasons(kept):  # GENEA's reasons (juiceOptions, juiceOtherReason) per system
        counts, reason_notes = reason_counts(kept)
        notes += reason_notes
        written += write_reasons(counts, out)
    written.insert(0, _summary(out, "Leaderboard", leaderboard_text(report), notes))
    shown = report.board[["task", "control_class", "rank", "system", "elo", "ci_low", "ci_high", "pages",
                          "warning"]]
    return [f"Elo with {origin_text(report.board)}", to_markdown(shown.round(1)), f"wrote {len(written)} files",
            *(f"note: {n}" for n in notes)]


def _write_genea_votes(ratings: pd.DataFrame, source: str, out: Path) -> Path:
    """Every vote of ``ratings`` (read from ``source``) as out/votes_genea.csv, in the
    source's own columns and line endings where it is a GENEA file."""
    with open(source, encoding="utf-8-sig", newline="") as file:
        text = file.read()
    layout = genea_layout(text) if any(c.startswith(CARRIED) for c in ratings.columns) else None
    path = out / GENEA_VOTES
    path.write_bytes(genea_csv(ratings, layout).encode("utf-8"))
    return path


def genea_votes_command(args: argparse.Namespace, out: Path) -> list[str]:
    ratings = read_ratings(args.ratings)
    design = design_of(ratings)
    if not (design.votes or design.judges_appropriateness):
        raise AnalysisInputError(f"genea-votes writes pairwise and appropriateness tables; {args.ratings} is "
                                 f"{design.name}")
    path = _write_genea_votes(ratings, args.ratings, out)
    return [f"wrote {path.name}"]


def simulate_pairing_command(args: argparse.Namespace, out: Path) -> list[str]:
    scenario = Scenario(args.elo, args.pages_per_participant, args.exploration, resamples=args.resamples)
    results = compare_pairings(scenario, args.studies, args.votes, args.seed, args.workers)
    written, text = write_pairing_simulation(scenario, results, out, args.studies, args.seed)
    return [text, f"wrote {len(written)} files"]


def rater_models_command(args: argparse.Namespace, out: Path) -> list[str]:
    kept, notes = _compared(args, lambda design: design.rated)
    if args.reference is not None and args.reference not in set(kept["system"]):
        raise AnalysisInputError(f"reference system {args.reference!r} has no compared ratings; "
                                 f"systems: {', '.join(sorted(set(kept['system'])))}")
    natural = exclusion_rules(args).natural_system
    reference = args.reference or (natural if natural in set(kept["system"]) else None)
    models = build_rater_models(kept, reference)
    notes += models.notes
    written = [_summary(out, "Rater- and clip-aware models", rater_models_text(models), notes),
               *write_rater_models(models, out)]
    return [rater_models_text(models), f"wrote {len(written)} files", *(f"note: {n}" for n in notes)]
