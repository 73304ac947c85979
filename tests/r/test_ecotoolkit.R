# Test of R/ecotoolkit.R (docs/r.md) against real eco outputs: run by CTest as
#   Rscript tests/r/test_ecotoolkit.R ECO_BINARY SOURCE_DIR
# Exit 77 (skipped) when hdf5r or spatstat.geom is missing. Makes a tiny scene with eco
# (a 60 x 45 terrain of 0.8 m cells re-based to (500, 1000) m), then checks the point
# patterns against the CSVs eco writes, the window against the generator's parameters,
# a grid against the ASCII grid we wrote, and the format checks. About 5 s.

args <- commandArgs(trailingOnly = TRUE)
eco <- normalizePath(args[1])
source_dir <- normalizePath(args[2])
for (p in c("hdf5r", "spatstat.geom")) {
  if (!requireNamespace(p, quietly = TRUE)) {
    cat("skipped: R package", p, "is missing (Debian: r-cran-hdf5r r-cran-spatstat.geom)\n")
    quit(status = 77)
  }
}
source(file.path(source_dir, "R", "ecotoolkit.R"))

failures <- 0
check <- function(ok, what) {
  if (!isTRUE(ok)) {
    cat("FAILED:", what, "\n")
    failures <<- failures + 1
  } else {
    cat("ok:", what, "\n")
  }
}

dir <- tempfile("ecotoolkit-r-")
dir.create(dir)
owd <- setwd(dir)
run <- function(...) {
  out <- system2(eco, c("--threads", "2", ...), stdout = TRUE, stderr = TRUE)
  status <- attr(out, "status")
  if (!is.null(status) && status != 0) stop(paste(c("eco", ..., "failed:", out), collapse = "\n"))
  invisible(out)
}
nx <- 60; ny <- 45; cell <- 0.8; x0 <- 500; y0 <- 1000
run("terrain", "generate", "--out", "generated.asc", "--width", nx, "--height", ny, "--cell-size", 1, "--seed", 4)
lines <- readLines("generated.asc")
body <- lines[!grepl("^(ncols|nrows|xllcorner|yllcorner|cellsize|nodata_value)", lines, ignore.case = TRUE)]
writeLines(c(paste("ncols", nx), paste("nrows", ny), paste("xllcorner", x0), paste("yllcorner", y0),
             paste("cellsize", cell), body), "input.asc")
asc <- as.matrix(read.table(text = body))  # row 1 = northern row
run("terrain", "convert", "input.asc", "terrain.h5")
run("chm", "generate", "--terrain", "terrain.h5", "--out", "chm.h5", "--seed", 2, "--sketch-seed", 3)
run("abiotics", "--terrain", "terrain.h5", "--out", "abiotics.h5", "--sun-step", 60)
run("canopy", "--terrain", "terrain.h5", "--chm", "chm.h5", "--abiotics", "abiotics.h5", "--out", "canopy.h5")
crop <- c(x0 + 8 * cell, y0 + 8 * cell, x0 + 58 * cell, y0 + 44 * cell)
run("simulate", "--abiotics", "abiotics.h5", "--canopy", "canopy.h5", "--terrain", "terrain.h5",
    "--crop", paste(crop, collapse = ","), "--years", 4, "--seed", 5, "--snapshot-years", 2,
    "--out", "sim.h5", "--csv", "sim.csv")
run("analyse", "sim.h5", "--out", "db.h5", "--kmax", 3)
run("synth", "--terrain", "terrain.h5", "--canopy", "canopy.h5", "--database", "db.h5",
    "--abiotics", "abiotics.h5", "--out", "scene.h5", "--csv", "scene.csv")

# The scene's undergrowth against its CSV; the window against the terrain we wrote.
pp <- eco_scene_ppp("scene.h5")
csv <- read.csv("scene.csv")
u <- csv[csv$layer == "undergrowth", ]
check(npoints(pp) == nrow(u), "scene: as many points as undergrowth rows in the CSV")
check(max(abs(pp$x - u$x_m)) < 6e-4 && max(abs(pp$y - u$y_m)) < 6e-4, "scene: positions match the CSV")
check(identical(as.character(marks(pp)), as.character(u$species)), "scene: marks are the CSV's species")
check(isTRUE(all.equal(c(Window(pp)$xrange, Window(pp)$yrange), c(x0, x0 + nx * cell, y0, y0 + ny * cell))),
      "scene: window is the terrain's extent")
canopy <- eco_scene_ppp("scene.h5", "canopy")
check(npoints(canopy) == sum(csv$layer == "canopy"), "scene: canopy layer")

# The last and the first snapshot of the simulation.
sp <- eco_simulation_ppp("sim.h5")
sim_csv <- read.csv("sim.csv")
check(npoints(sp) == nrow(sim_csv), "simulation: last snapshot has the CSV's plants")
check(max(abs(sp$x - sim_csv$x_m)) < 6e-5 && max(abs(sp$y - sim_csv$y_m)) < 6e-5, "simulation: positions")
check(identical(as.character(marks(sp)), as.character(sim_csv$species)), "simulation: species")
check(isTRUE(all.equal(c(Window(sp)$xrange, Window(sp)$yrange), crop[c(1, 3, 2, 4)])), "simulation: window is the crop")
check(npoints(eco_simulation_ppp("sim.h5", 2)) > 0, "simulation: year 2 snapshot")
check(inherits(try(eco_simulation_ppp("sim.h5", 3), silent = TRUE), "try-error"), "simulation: no year 3 snapshot")

# A grid: z[ix, iy] with iy = 1 the southern row, against the ASCII grid (row 1 northern).
f <- eco_open("terrain.h5", "eco-terrain")
g <- eco_grid(f, "terrain/elevation")
f$close_all()
check(isTRUE(all.equal(dim(g$z), c(nx, ny))), "grid: [x, y] dimensions")
check(max(abs(g$z - t(asc[ny:1, ]))) < 1e-4 * max(abs(asc)), "grid: values match the ASCII grid")
check(isTRUE(all.equal(range(g$x), c(x0 + cell / 2, x0 + (nx - 0.5) * cell))), "grid: x of cell centres")
check(isTRUE(all.equal(range(g$y), c(y0 + cell / 2, y0 + (ny - 0.5) * cell))), "grid: y of cell centres")
check(g$units == "m", "grid: units")

# Format checks.
e <- try(eco_scene_ppp("terrain.h5"), silent = TRUE)
check(grepl("terrain.h5: format 'eco-terrain', expected 'eco-scene'", e, fixed = TRUE), "refuses another kind")
invisible(file.copy("scene.h5", "scene-v99.h5"))
f <- H5File$new("scene-v99.h5", mode = "r+")
f$attr_delete("schema_version")
h5attr(f, "schema_version") <- 99L
f$close_all()
e <- try(eco_scene_ppp("scene-v99.h5"), silent = TRUE)
check(grepl("schema_version 99 found, this recipe reads version 1", e, fixed = TRUE), "refuses an unknown version")

setwd(owd)
unlink(dir, recursive = TRUE)
if (failures > 0) quit(status = 1)
cat("all R checks passed\n")
