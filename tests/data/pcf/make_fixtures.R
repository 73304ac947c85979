# Reference pair-correlation values for tests/pcf_test.cpp, computed by spatstat.
#
# How to run (Debian 12, from the repository root; needs the packages r-base-core and
# r-cran-spatstat, which CI does not install: the test only reads the committed CSVs):
#
#   Rscript tests/data/pcf/make_fixtures.R tests/data/pcf
#
# For each pattern it writes NAME_points.csv (header x,y[,species]; coordinates with 17
# significant digits, read back before any computation, so R and C++ see the same numbers)
# and NAME_spatstat.csv with, per ordered type pair and distance bin [r_lo, r_hi):
#   K_trans_lo, K_trans_hi   spatstat's K (Kest for one type, Kcross for two) with
#                            correction = "translate" at the bin edges
#   g_trans  = (K_trans_hi - K_trans_lo) / (pi (r_hi^2 - r_lo^2))
#   g_iso    = the same with correction = "isotropic" (Ripley)
# i.e. the annulus estimator of g that eco's estimator implements (core/point_pattern.h).
# The window is the rectangle [10, 110] x [20, 80] m (non-square, offset from the origin).
suppressPackageStartupMessages(library(spatstat))

args <- commandArgs(trailingOnly = TRUE)
outdir <- if (length(args) >= 1) args[1] else "."
set.seed(20240501)

W <- owin(c(10, 110), c(20, 80))
rmax <- 15
nbins <- 30
edges <- seq(0, rmax, length.out = nbins + 1)

write_points <- function(X, name) {
  path <- file.path(outdir, paste0(name, "_points.csv"))
  lines <- if (is.marked(X)) {
    sprintf("%.17g,%.17g,%s", X$x, X$y, as.character(marks(X)))
  } else {
    sprintf("%.17g,%.17g", X$x, X$y)
  }
  header <- if (is.marked(X)) "x,y,species" else "x,y"
  writeLines(c(header, lines), path)
  # Read back: the reference is computed on exactly the values in the file.
  d <- read.csv(path, colClasses = if (is.marked(X)) c("numeric", "numeric", "character") else c("numeric", "numeric"))
  if (is.marked(X)) ppp(d$x, d$y, window = W, marks = factor(d$species)) else ppp(d$x, d$y, window = W)
}

annulus <- function(K) diff(K) / (pi * diff(edges^2))

rows <- function(from, to, Kt, Ki) {
  data.frame(from = from, to = to, r_lo = head(edges, -1), r_hi = tail(edges, -1),
             K_trans_lo = head(Kt, -1), K_trans_hi = tail(Kt, -1),
             g_trans = annulus(Kt), g_iso = annulus(Ki))
}

one_type <- function(X, label) {
  K <- Kest(X, r = edges, correction = c("translate", "isotropic"), nlarge = Inf)
  rows(label, label, K$trans, K$iso)
}

write_reference <- function(df, name) {
  path <- file.path(outdir, paste0(name, "_spatstat.csv"))
  df[] <- lapply(df, function(col) if (is.numeric(col)) sprintf("%.17g", col) else col)
  write.csv(df, path, row.names = FALSE, quote = FALSE)
}

# 1. Poisson (complete spatial randomness): g = 1.
X <- write_points(rpoispp(0.15, win = W), "poisson")
write_reference(one_type(X, "all"), "poisson")

# 2. Clustered: Thomas process (parents 0.004 / m2, 15 offspring each, sd 2.5 m).
X <- write_points(rThomas(kappa = 0.004, scale = 2.5, mu = 15, win = W), "thomas")
write_reference(one_type(X, "all"), "thomas")

# 3. Inhibited: hard-core process (perfect simulation), hard core 2 m.
X <- write_points(rHardcore(beta = 0.08, R = 2, W = W), "hardcore")
write_reference(one_type(X, "all"), "hardcore")

# 4. Two types: "oak" Poisson, "fern" clustered around the oaks (within 4 m), plus some
#    Poisson ferns: positive cross-correlation at short range.
oak <- rpoispp(0.03, win = W)
fx <- c(); fy <- c()
for (i in seq_len(npoints(oak))) {
  n <- rpois(1, 5)
  if (n == 0) next
  rr <- 4 * sqrt(runif(n)); th <- runif(n, 0, 2 * pi)
  fx <- c(fx, oak$x[i] + rr * cos(th)); fy <- c(fy, oak$y[i] + rr * sin(th))
}
keep <- inside.owin(fx, fy, W)
extra <- rpoispp(0.02, win = W)
fern <- ppp(c(fx[keep], extra$x), c(fy[keep], extra$y), window = W)
X <- superimpose(oak = oak, fern = fern, W = W)
X <- write_points(X, "bivariate")
ref <- list()
for (a in levels(marks(X))) {
  for (b in levels(marks(X))) {
    if (a == b) {
      ref[[length(ref) + 1]] <- one_type(X[marks(X) == a], a)
    } else {
      K <- Kcross(X, a, b, r = edges, correction = c("translate", "isotropic"))
      ref[[length(ref) + 1]] <- rows(a, b, K$trans, K$iso)
    }
  }
}
ref[[length(ref) + 1]] <- one_type(unmark(X), "all")
write_reference(do.call(rbind, ref), "bivariate")

cat("wrote fixtures to", outdir, "\n")
