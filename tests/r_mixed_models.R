# lme4's and ordinal's fits of the crossed mixed models, the reference the tests compare
# the project's own with:
#
#   Rscript tests/r_mixed_models.R FOLDER
#
# For every FOLDER/NAME.csv (columns participant, stimulus, system, value; the first
# system in the file's order is the reference) it writes FOLDER/NAME.lmer.csv and
# FOLDER/NAME.clmm.csv, two columns: term, estimate.
#   lmer:  value ~ 0 + system + (1 | participant) + (1 | stimulus) by REML: each system's
#          mean (term = the system), the participant, stimulus and residual variances and
#          the REML criterion (-2 restricted log-likelihood).
#   clmm:  ordered(value) ~ system + (1 | participant) + (1 | stimulus), logit link,
#          flexible thresholds, Laplace (nAGQ = 1): the thresholds ("1|2", ...), the
#          system effects against the reference (term = the system), the participant and
#          stimulus variances and the log-likelihood.
# Both with the packages' default optimisers and settings (clmm without the Hessian: no
# standard errors are compared, and it takes as long as the fit).
suppressPackageStartupMessages({
  library(lme4)
  library(ordinal)
})

folder <- commandArgs(trailingOnly = TRUE)[1]
write_terms <- function(terms, estimates, path) {
  write.csv(data.frame(term = terms, estimate = estimates), path, row.names = FALSE)
}

for (path in list.files(folder, pattern = "\\.csv$", full.names = TRUE)) {
  if (grepl("\\.(lmer|clmm)\\.csv$", path)) next
  stem <- sub("\\.csv$", "", path)
  ratings <- read.csv(path, colClasses = c(participant = "character", stimulus = "character",
                                           system = "character"))
  ratings$system <- factor(ratings$system, levels = unique(ratings$system))

  linear <- lmer(value ~ 0 + system + (1 | participant) + (1 | stimulus), data = ratings, REML = TRUE)
  components <- as.data.frame(VarCorr(linear))
  variance <- setNames(components$vcov, components$grp)
  write_terms(c(levels(ratings$system), "participant_var", "stimulus_var", "residual_var", "reml_criterion"),
              c(unname(fixef(linear)), variance[c("participant", "stimulus", "Residual")],
                unname(REMLcrit(linear))),
              paste0(stem, ".lmer.csv"))

  ratings$rating <- factor(ratings$value, levels = sort(unique(ratings$value)), ordered = TRUE)
  cumulative <- clmm(rating ~ system + (1 | participant) + (1 | stimulus), data = ratings, link = "logit",
                     threshold = "flexible", nAGQ = 1, Hess = FALSE)
  # VarCorr(clmm) names the factors by their level counts sorted with ties reversed, so
  # with as many participants as clips it swaps their names; ST, the relative factors,
  # is in the order of the grouping factors (gfList), which keep theirs.
  sds <- abs(sapply(cumulative$ST, function(st) st[1, 1]))
  names(sds) <- names(cumulative$gfList)
  write_terms(c(names(cumulative$alpha), levels(ratings$system)[-1], "participant_var", "stimulus_var",
                "log_likelihood"),
              c(unname(cumulative$alpha), unname(cumulative$beta), unname(sds[c("participant", "stimulus")])^2,
                as.numeric(logLik(cumulative))),
              paste0(stem, ".clmm.csv"))
}
