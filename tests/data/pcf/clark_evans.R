# Reference Clark-Evans indices (Donnelly edge correction) and mean nearest-neighbour
# distances of the committed fixture patterns, by spatstat, for tests/pcf_test.cpp.
#   Rscript tests/data/pcf/clark_evans.R tests/data/pcf > tests/data/pcf/clark_evans_spatstat.csv
suppressPackageStartupMessages(library(spatstat))
args <- commandArgs(trailingOnly = TRUE)
dir <- if (length(args) >= 1) args[1] else "."
W <- owin(c(10, 110), c(20, 80))
cat("pattern,n,mean_nn,clark_evans_donnelly\n")
for (name in c("poisson", "thomas", "hardcore", "bivariate")) {
  p <- read.csv(file.path(dir, paste0(name, "_points.csv")))
  X <- ppp(p$x, p$y, window = W)
  cat(sprintf("%s,%d,%.17g,%.17g\n", name, npoints(X), mean(nndist(X)),
              clarkevans(X, correction = "Donnelly")[[1]]))
}
