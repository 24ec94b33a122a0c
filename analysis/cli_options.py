"""Command-line options several `analysis` commands share: which ratings the exclusion
rules remove, and whether the attention-check system is compared instead."""

from __future__ import annotations

import argparse

from analysis.exclusions import ExclusionRules


def add_exclusion_arguments(parser: argparse.ArgumentParser, thresholds: bool = True) -> None:
    """The exclusion rules' options; ``thresholds`` adds the rating thresholds (not for
    pairwise tables, whose rule is a preference for the attention-check clip)."""
    parser.add_argument("--natural", default="NAT", help="name of the natural-motion system")
    parser.add_argument("--attention", default="BAD", help="name of the attention-check system")
    if thresholds:
        parser.add_argument("--bad-threshold", type=float, default=4.0,
                            help="exclude a participant rating any attention clip at or above this "
                                 "(on a 1-5 scale, rescaled for others; default 4)")
        parser.add_argument("--nat-threshold", type=float, default=2.0,
                            help="exclude a participant rating any natural clip below this "
                                 "(on a 1-5 scale; default 2)")
    parser.add_argument("--keep-early", action="store_true",
                        help="do not discard ratings given before the clip ended")
    parser.add_argument("--compare-attention-checks", action="store_true",
                        help="compare the attention-check system like any other, and exclude "
                             "nobody for how they rated or preferred it")


def exclusion_rules(args: argparse.Namespace) -> ExclusionRules:
    """The rules the options of `add_exclusion_arguments` name."""
    defaults = ExclusionRules()
    return ExclusionRules(natural_system=args.natural, attention_system=args.attention,
                          bad_at_or_above=getattr(args, "bad_threshold", defaults.bad_at_or_above),
                          natural_below=getattr(args, "nat_threshold", defaults.natural_below),
                          discard_early=not args.keep_early,
                          attention_rule=not args.compare_attention_checks)
