"""Command-line options several `analysis` commands share: which ratings the exclusion
rules remove, and whether the attention-check system is compared instead. The rules come
as options or all at once from a JSON file (the study app's rules.json, which reproduces
its report), not both."""

from __future__ import annotations

import argparse
from pathlib import Path

from analysis.errors import AnalysisInputError
from analysis.exclusion_rules import ExclusionRules


def add_exclusion_arguments(parser: argparse.ArgumentParser, thresholds: bool = True) -> None:
    """The exclusion rules' options; ``thresholds`` adds the rating thresholds (not for
    pairwise tables, whose rule is a preference for the attention-check clip)."""
    rules = parser.add_argument_group(
        "exclusion rules", "as options, or all at once with --rules (the study app's rules.json, which "
                           "reproduces its report); not both")
    rules.add_argument("--rules", metavar="RULES.json",
                       help="the exclusion rules as JSON: natural_system, attention_system, "
                            "bad_at_or_above, natural_below, discard_early, attention_rule")
    rules.add_argument("--natural", help="name of the natural-motion system (default NAT)")
    rules.add_argument("--attention", help="name of the attention-check system (default BAD)")
    if thresholds:
        rules.add_argument("--bad-threshold", type=float,
                           help="exclude a participant rating any attention clip at or above this "
                                "(on a 1-5 scale, rescaled for others; default 4)")
        rules.add_argument("--nat-threshold", type=float,
                           help="exclude a participant rating any natural clip below this "
                                "(on a 1-5 scale; default 2)")
    rules.add_argument("--keep-early", action="store_true",
                       help="do not discard ratings given before the clip ended")
    rules.add_argument("--compare-attention-checks", action="store_true",
                       help="compare the attention-check system like any other, and exclude "
                            "nobody for how they rated or preferred it")


def exclusion_rules(args: argparse.Namespace) -> ExclusionRules:
    """The rules the options of `add_exclusion_arguments` name, or those of the --rules file."""
    options = {"natural_system": args.natural, "attention_system": args.attention,
               "bad_at_or_above": getattr(args, "bad_threshold", None),
               "natural_below": getattr(args, "nat_threshold", None),
               "discard_early": False if args.keep_early else None,
               "attention_rule": False if args.compare_attention_checks else None}
    given = {name: value for name, value in options.items() if value is not None}
    if args.rules is None:
        return ExclusionRules(**given)
    if given:
        raise AnalysisInputError("give the exclusion rules with --rules or as options, not both")
    try:
        text = Path(args.rules).read_text(encoding="utf-8")
    except OSError as exc:
        raise AnalysisInputError(f"cannot read --rules {args.rules}: {exc.strerror}") from None
    except UnicodeDecodeError:
        raise AnalysisInputError(f"--rules {args.rules} is not UTF-8 text") from None
    return ExclusionRules.from_json(text, source=args.rules)
