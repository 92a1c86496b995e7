#!/usr/bin/env Rscript
# Assertions of the R-recipe test (tests/r/r_recipe_test.sh) on the phantom cohort:
#  * every parameter the phantom gives a group effect has GEE p < 0.05;
#  * every asserted null (true group difference exactly 0, docs/phantoms.md) has p >= 0.05;
#  * octshape stats --retest ICC(2,1) and its 95 % CI equal psych::ICC's ICC2 to 3 decimals
#    (|difference| < 5e-4) for every parameter both report.
# Usage: Rscript check_phantom_cohort.R gee.csv icc_r.csv icc_octshape.csv expected.csv
args <- commandArgs(trailingOnly = TRUE)
gee <- read.csv(args[1], stringsAsFactors = FALSE)
icc_r <- read.csv(args[2], stringsAsFactors = FALSE)
icc_o <- read.csv(args[3], stringsAsFactors = FALSE, na.strings = "NA")
expected <- read.csv(args[4], stringsAsFactors = FALSE)

failures <- character(0)
fail <- function(...) failures <<- c(failures, paste0(...))

cat("GEE p-values on the phantom cohort (case vs control):\n")
for (j in seq_len(nrow(expected))) {
  p <- expected$parameter[j]
  row <- gee[gee$parameter == p, ]
  if (nrow(row) != 1) { fail(p, ": no GEE result"); next }
  cat(sprintf("  %-24s %-6s estimate %+.5g  p = %.3g\n", p, expected$expected[j],
              row$estimate, row$p))
  if (expected$expected[j] == "effect" && !(row$p < 0.05)) fail(p, ": effect not found, p = ", row$p)
  if (expected$expected[j] == "null" && !(row$p >= 0.05)) fail(p, ": null rejected, p = ", row$p)
}

cat("ICC(2,1): octshape stats vs psych::ICC (ICC2):\n")
compared <- 0
worst <- 0
for (j in seq_len(nrow(icc_r))) {
  p <- icc_r$parameter[j]
  o <- icc_o[icc_o$parameter == p, ]
  if (nrow(o) != 1) { fail(p, ": octshape has no ICC"); next }
  if (o$n_eyes != icc_r$n_eyes[j] || o$k != icc_r$k[j]) {
    fail(p, ": different retest sets (octshape n=", o$n_eyes, " k=", o$k, ", R n=",
         icc_r$n_eyes[j], " k=", icc_r$k[j], ")")
    next
  }
  for (col in c("icc", "lower_95", "upper_95")) {
    a <- o[[col]]
    b <- icc_r[[col]][j]
    if (is.na(a) != is.na(b)) { fail(p, " ", col, ": NA in one only"); next }
    if (is.na(a)) next
    worst <- max(worst, abs(a - b))
    if (abs(a - b) >= 5e-4) fail(p, " ", col, ": octshape ", a, " vs psych ", b)
  }
  compared <- compared + 1
  if (p %in% expected$parameter || p == "rmse_um") {
    cat(sprintf("  %-24s octshape %.4f [%.4f, %.4f]  psych %.4f [%.4f, %.4f]\n", p, o$icc,
                o$lower_95, o$upper_95, icc_r$icc[j], icc_r$lower_95[j], icc_r$upper_95[j]))
  }
}
cat(sprintf("  %d parameters compared, largest |difference| %.3g\n", compared, worst))
if (compared < 10) fail("only ", compared, " ICCs compared")

if (length(failures) > 0) {
  cat("FAILED:\n", paste0("  ", failures, "\n"), sep = "")
  quit(status = 1)
}
cat("OK\n")
