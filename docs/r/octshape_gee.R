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
#                                    [--retest] [--same-visit] [--icc-out icc.csv]
# Needs the Debian packages r-base-core r-cran-geepack r-cran-psych (r-cran-lme4 for psych).

suppressPackageStartupMessages({
  library(geepack)
  library(psych)
})

args <- commandArgs(trailingOnly = TRUE)
opt <- list(file = NA, group_col = "group", ref = NA, out = NA, retest = FALSE,
            same_visit = FALSE, icc_out = NA)
i <- 1
while (i <= length(args)) {
  a <- args[i]
  value <- function() {
    if (i + 1 > length(args)) stop("option ", a, " needs a value")
    args[i + 1]
  }
  if (a == "--group-col") { opt$group_col <- value(); i <- i + 1 }
  else if (a == "--ref") { opt$ref <- value(); i <- i + 1 }
  else if (a == "--out") { opt$out <- value(); i <- i + 1 }
  else if (a == "--icc-out") { opt$icc_out <- value(); i <- i + 1 }
  else if (a == "--retest") opt$retest <- TRUE
  else if (a == "--same-visit") opt$same_visit <- TRUE
  else if (startsWith(a, "--")) stop("unknown option ", a)
  else opt$file <- a
  i <- i + 1
}
if (is.na(opt$file)) stop("usage: Rscript octshape_gee.R eyes.csv [options]")

# "NA" is octshape's missing value; keep identifiers as text.
d <- read.csv(opt$file, na.strings = c("NA", ""), stringsAsFactors = FALSE,
              check.names = FALSE,
              colClasses = c(subject_id = "character", eye = "character",
                             visit_date = "character", eye_key = "character"))
id_cols <- c("subject_id", "eye", "visit_date", "scan_type", "eye_key", "sha256", "group",
             opt$group_col)
params <- names(d)[vapply(names(d), function(n) {
  !(n %in% id_cols) && is.numeric(d[[n]]) && any(!is.na(d[[n]]))
}, logical(1))]

# ---- 1. GEE per parameter -------------------------------------------------------------------
# One scan per eye: the first by visit_date, then eye_key (as `octshape stats`).
d <- d[order(d$subject_id, d$eye, d$visit_date, d$eye_key, method = "radix"), ]  # byte order
eyes <- d[!duplicated(d[, c("subject_id", "eye")]), ]
if (!(opt$group_col %in% names(eyes))) stop("no column '", opt$group_col, "' in ", opt$file)
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
gee <- if (length(gee_rows) > 0) do.call(rbind, gee_rows) else data.frame()
cat("GEE (gaussian, exchangeable working correlation within subject; robust SE; Wald p)\n")
print(format(gee, digits = 4), row.names = FALSE)
if (!is.na(opt$out)) write.csv(gee, opt$out, row.names = FALSE, na = "NA")

# ---- 2. ICC for repeated scans --------------------------------------------------------------
if (opt$retest) {
  key <- if (opt$same_visit) paste(d$subject_id, d$eye, d$visit_date, sep = "\r") else
    paste(d$subject_id, d$eye, sep = "\r")
  d$key_ <- key
  counts <- table(d$key_)
  repeated <- names(counts)[counts >= 2]
  if (length(repeated) == 0) stop("--retest: no eye has two scans")
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
  icc <- if (length(icc_rows) > 0) do.call(rbind, icc_rows) else data.frame()
  cat("\nICC(2,1) (psych::ICC 'ICC2': two-way random, absolute agreement, single measurement)\n")
  print(format(icc, digits = 4), row.names = FALSE)
  if (!is.na(opt$icc_out)) write.csv(icc, opt$icc_out, row.names = FALSE, na = "NA")
}
