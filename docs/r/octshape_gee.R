#!/usr/bin/env Rscript
# octshape GEE / ICC recipe (docs/r/README.md).
#
# Reads an octshape eyes.csv and
#  1. for every numeric parameter fits geepack::geeglm(param ~ group, id = subject,
#     corstr = "exchangeable") on one scan per eye (the first by visit_date, then eye_key), with
#     the rows sorted by subject as geeglm requires, and prints estimate, robust SE and Wald
#     p-value of every group contrast against the reference group;
#  2. with --retest, computes psych::ICC on the eyes scanned more than once (the same eyes,
#     scans and order as `octshape stats --retest`) and prints ICC2 = ICC(2,1) with its 95 % CI.
#
# Usage:
#   Rscript octshape_gee.R eyes.csv [--group-col group] [--ref LEVEL] [--out gee.csv]
#                                    [--analysis volume|radial|line] [--retest] [--same-visit]
#                                    [--icc-out icc.csv]
# Needs the Debian packages r-base-core r-cran-geepack r-cran-psych (r-cran-lme4 for psych).
#
# One analysis a table: the rows of one `analysis` (volume, radial or line; default: volume when
# there are volume rows, else radial, else line) are used, the others left out with one line
# saying how many (as `octshape stats`). What it cannot do it refuses with one line
# "octshape_gee.R: error: ..." on stderr: exit 64 for a command-line mistake, 65 for a table it
# cannot use (no such file or column, no row of the analysis, fewer than two groups for the GEE
# without --retest).

refuse <- function(status, ...) {
  cat("octshape_gee.R: error: ", ..., "\n", sep = "", file = stderr())
  quit(save = "no", status = status)
}

args <- commandArgs(trailingOnly = TRUE)
opt <- list(file = NA, group_col = "group", ref = NA, out = NA, retest = FALSE,
            same_visit = FALSE, icc_out = NA, analysis = NA)
i <- 1
while (i <= length(args)) {
  a <- args[i]
  value <- function() {
    if (i + 1 > length(args)) refuse(64, "option ", a, " needs a value")
    args[i + 1]
  }
  if (a == "--group-col") { opt$group_col <- value(); i <- i + 1 }
  else if (a == "--ref") { opt$ref <- value(); i <- i + 1 }
  else if (a == "--out") { opt$out <- value(); i <- i + 1 }
  else if (a == "--icc-out") { opt$icc_out <- value(); i <- i + 1 }
  else if (a == "--analysis") { opt$analysis <- value(); i <- i + 1 }
  else if (a == "--retest") opt$retest <- TRUE
  else if (a == "--same-visit") opt$same_visit <- TRUE
  else if (startsWith(a, "--")) refuse(64, "unknown option ", a)
  else opt$file <- a
  i <- i + 1
}
if (is.na(opt$file)) refuse(64, "usage: Rscript octshape_gee.R eyes.csv [options]")
if (!is.na(opt$analysis) && !(opt$analysis %in% c("volume", "radial", "line"))) {
  refuse(64, "--analysis must be volume, radial or line, not '", opt$analysis, "'")
}
if (!file.exists(opt$file)) refuse(65, opt$file, ": no such file")

header <- names(read.csv(opt$file, nrows = 1, check.names = FALSE))
for (col in c("subject_id", "eye", "visit_date", "eye_key")) {
  if (!(col %in% header)) refuse(65, opt$file, ": no column '", col, "' (not an eyes table)")
}
# "NA" is octshape's missing value; keep identifiers as text.
d <- read.csv(opt$file, na.strings = c("NA", ""), stringsAsFactors = FALSE,
              check.names = FALSE,
              colClasses = c(subject_id = "character", eye = "character",
                             visit_date = "character", eye_key = "character"))
# Columns that identify or describe a scan, never parameters (the record's, tested against
# octshape's own list: tests/retina/record_test.cpp).
id_cols <- c("subject_id", "eye", "visit_date", "scan_type", "eye_key", "sha256", "group",
             "analysis", "scan_pattern", "num_bscans", "fingerprint")

# One analysis a table (as `octshape stats`): never pooled.
if ("analysis" %in% names(d)) {
  present <- unique(d$analysis)
  keep <- opt$analysis
  if (is.na(keep)) {
    keep <- c("volume", "radial", "line")[c("volume", "radial", "line") %in% present][1]
    if (is.na(keep)) keep <- sort(present)[1]
  }
  if (!any(!is.na(d$analysis) & d$analysis == keep)) {
    refuse(65, opt$file, ": no row of analysis '", keep, "'")
  }
  for (other in sort(setdiff(present, keep))) {
    message("octshape_gee.R: ", opt$file, ": ", sum(d$analysis == other, na.rm = TRUE),
            " rows of analysis '", other, "' left out (one analysis a table: give --analysis ",
            other, ")")
  }
  d <- d[!is.na(d$analysis) & d$analysis == keep, ]
  cat("Analysis: ", keep, "\n", sep = "")
} else if (!is.na(opt$analysis)) {
  refuse(65, opt$file, ": no column 'analysis' for --analysis ", opt$analysis)
}

params <- names(d)[vapply(names(d), function(n) {
  !(n %in% c(id_cols, opt$group_col)) && is.numeric(d[[n]]) && any(!is.na(d[[n]]))
}, logical(1))]

# The GEE compares groups: it needs two (a cohort run without --groups has none).
groups <- if (opt$group_col %in% names(d)) unique(d[[opt$group_col]][!is.na(d[[opt$group_col]])]) else c()
do_gee <- length(groups) >= 2
if (!do_gee) {
  why <- if (!(opt$group_col %in% names(d))) paste0("no column '", opt$group_col, "'") else
    paste0(length(groups), " group(s) in column '", opt$group_col, "'")
  if (!opt$retest) {
    refuse(65, opt$file, ": the GEE needs two groups, found ", why,
           " (run the cohort with --groups, or give --retest for the ICC alone)")
  }
  message("octshape_gee.R: ", opt$file, ": no GEE (", why, "); the ICC only")
}

suppressPackageStartupMessages({
  library(geepack)
  library(psych)
})

# A result table (a list of one-row data frames): printed under `title`, written to `out` (a
# path, or NA); refused (one line, exit 65) when empty, instead of an empty frame and exit 0.
show <- function(rows, empty, title, out) {
  if (length(rows) == 0) refuse(65, opt$file, ": ", empty)
  t <- do.call(rbind, rows)
  cat(title, "\n", sep = "")
  print(format(t, digits = 4), row.names = FALSE)
  if (!is.na(out)) write.csv(t, out, row.names = FALSE, na = "NA")
}

# ---- 1. GEE per parameter -------------------------------------------------------------------
# One scan per eye: the first by visit_date, then eye_key (as `octshape stats`).
d <- d[order(d$subject_id, d$eye, d$visit_date, d$eye_key, method = "radix"), ]  # byte order
if (do_gee) {
  eyes <- d[!duplicated(d[, c("subject_id", "eye")]), ]
  eyes <- eyes[!is.na(eyes[[opt$group_col]]) & !is.na(eyes$subject_id), ]
  eyes$group_ <- factor(eyes[[opt$group_col]])
  if (!is.na(opt$ref)) eyes$group_ <- relevel(eyes$group_, ref = opt$ref)
  # geeglm takes consecutive rows with the same id as one cluster: sort by subject.
  eyes <- eyes[order(eyes$subject_id, eyes$eye, method = "radix"), ]

  gee_rows <- list()
  for (p in params) {
    sub <- eyes[!is.na(eyes[[p]]), c("subject_id", "group_", p)]
    names(sub) <- c("subject_id", "group_", "y")
    sub$group_ <- droplevels(sub$group_)
    if (nlevels(sub$group_) < 2) next
    sub$id <- factor(sub$subject_id, levels = unique(sub$subject_id))
    fit <- tryCatch(
      geeglm(y ~ group_, id = id, data = sub, family = gaussian, corstr = "exchangeable"),
      error = function(e) e)
    if (inherits(fit, "error")) {
      message(p, ": geeglm failed: ", conditionMessage(fit))
      next
    }
    co <- summary(fit)$coefficients
    for (term in rownames(co)[-1]) {
      gee_rows[[length(gee_rows) + 1]] <- data.frame(
        parameter = p,
        contrast = paste0(sub("^group_", "", term), " - ", levels(sub$group_)[1]),
        estimate = co[term, "Estimate"],
        robust_se = co[term, "Std.err"],
        wald = co[term, "Wald"],
        p = co[term, "Pr(>|W|)"],
        n_eyes = nrow(sub),
        n_subjects = nlevels(sub$id),
        stringsAsFactors = FALSE)
    }
  }
  show(gee_rows, "the GEE fitted no parameter (each needs eyes in two groups)",
       "GEE (gaussian, exchangeable working correlation within subject; robust SE; Wald p)",
       opt$out)
}

# ---- 2. ICC for repeated scans --------------------------------------------------------------
if (opt$retest) {
  key <- if (opt$same_visit) paste(d$subject_id, d$eye, d$visit_date, sep = "\r") else
    paste(d$subject_id, d$eye, sep = "\r")
  d$key_ <- key
  counts <- table(d$key_)
  repeated <- names(counts)[counts >= 2]
  if (length(repeated) == 0) refuse(65, opt$file, ": --retest: no eye has two scans")
  k <- min(counts[repeated])
  # The first k scans of each repeated eye, in visit_date then eye_key order (d is sorted so).
  icc_rows <- list()
  for (p in params) {
    m <- do.call(rbind, lapply(repeated, function(r) d[d$key_ == r, p][seq_len(k)]))
    m <- m[stats::complete.cases(m), , drop = FALSE]
    if (nrow(m) < 2) next
    # lmer = FALSE: the classical two-way ANOVA mean squares of Shrout & Fleiss (the lme4
    # default truncates a negative variance component at 0 and then differs).
    r <- suppressMessages(psych::ICC(m, lmer = FALSE))$results
    row <- r[r$type == "ICC2", ]
    icc_rows[[length(icc_rows) + 1]] <- data.frame(
      parameter = p, n_eyes = nrow(m), k = k, icc = row$ICC,
      lower_95 = row[["lower bound"]], upper_95 = row[["upper bound"]],
      f = row$F, p = row$p, stringsAsFactors = FALSE)
  }
  show(icc_rows, "--retest: no parameter has two repeated eyes with values",
       "\nICC(2,1) (psych::ICC 'ICC2': two-way random, absolute agreement, single measurement)",
       opt$icc_out)
}
