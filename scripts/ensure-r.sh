#!/usr/bin/env bash
# Make sure R can load lme4 and ordinal, for the tests that compare the crossed mixed
# models with R's own fits (tests/test_analysis_mixed_models_against_r.py).
#
# If `Rscript -e 'library(lme4); library(ordinal)'` already works, nothing happens.
# Otherwise R and both packages are installed from the system's packages (Debian's
# r-base-core, r-cran-lme4 and r-cran-ordinal), never from CRAN. Running it again is harmless.
set -euo pipefail

say() { echo "ensure-r: $*" >&2; }

loads() { Rscript -e 'suppressPackageStartupMessages({library(lme4); library(ordinal)})' >/dev/null 2>&1; }

if loads; then
    exit 0
fi
"$(dirname "${BASH_SOURCE[0]}")/apt-install.sh" r-base-core r-cran-lme4 r-cran-ordinal
if loads; then
    say "R loads lme4 and ordinal"
    exit 0
fi
say "R is installed but cannot load lme4 and ordinal; what it says:"
Rscript -e 'library(lme4); library(ordinal)' >&2 || true
exit 1
