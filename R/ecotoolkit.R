# Read eco's HDF5 outputs from R with hdf5r and turn plant tables into spatstat point
# patterns (docs/r.md). Debian: apt-get install r-base-core r-cran-hdf5r r-cran-spatstat.geom
# Use: source("R/ecotoolkit.R"); pp <- eco_scene_ppp("out/demo/scene.h5")
#
# The layouts are those of docs/hdf5.md. hdf5r shows a C-order dataset [height][width] as an
# R matrix [width, height]: z[ix, iy] with iy = 1 the southern row, which is the order
# graphics::image(x, y, z) draws north up.

suppressPackageStartupMessages({
  library(hdf5r)
  library(spatstat.geom)
})

#: Formats and the schema versions read (python/ecotoolkit/_h5.py FORMATS holds the same).
eco_formats <- list(
  "eco-terrain" = 1, "eco-chm" = 1, "eco-abiotics" = c(1, 2), "eco-canopy" = c(1, 2),
  "eco-simulation" = c(1, 2), "eco-biome-db" = c(2, 3, 4, 5), "eco-scene" = 1
)

#' Open an eco HDF5 file read-only and check its root format and schema_version; stops
#' with a message naming the file, what was found and what was expected.
eco_open <- function(path, format) {
  f <- H5File$new(path, mode = "r")
  fail <- function(msg) {
    f$close_all()
    stop(paste0(path, ": ", msg), call. = FALSE)
  }
  if (!f$attr_exists("format")) fail(paste0("root attribute 'format' is missing (expected '", format, "')"))
  found <- h5attr(f, "format")
  if (!identical(found, format)) fail(paste0("format '", found, "', expected '", format, "'"))
  version <- if (f$attr_exists("schema_version")) h5attr(f, "schema_version") else NA
  if (is.na(version) || !(version %in% eco_formats[[format]]))
    fail(paste0("format '", format, "' schema_version ", version, " found, this recipe reads version ",
                paste(eco_formats[[format]], collapse = ", ")))
  f
}

#' A plant group (e.g. "undergrowth", "canopy", "snapshots/year_0150") as a data.frame:
#' species (factor in biome order), species_id, x, y, ground_z, height, crown_radius (m),
#' and the state columns of a simulation snapshot (id, age, ...) where present.
eco_plants <- function(f, group) {
  g <- f[[group]]
  names <- g[["species_names"]][]
  id <- g[["species_id"]][]
  df <- data.frame(species = factor(names[id + 1], levels = names), species_id = id)
  for (column in c("id", "x", "y", "ground_z", "height", "crown_radius", "age", "growth_age", "vigour",
                   "pool", "sun_share", "water_share"))
    if (g$exists(column)) df[[column]] <- g[[column]][]
  df
}

#' A grid dataset as list(x, y, z, units): x, y the cell centres in world metres, z[ix, iy]
#' (a monthly stack: z[ix, iy, month]).
eco_grid <- function(f, name) {
  d <- f[[name]]
  cell <- h5attr(d, "cell_size_m")
  z <- d$read()
  list(x = h5attr(d, "origin_x_m") + (seq_len(dim(z)[1]) - 0.5) * cell,
       y = h5attr(d, "origin_y_m") + (seq_len(dim(z)[2]) - 0.5) * cell,
       z = z, units = h5attr(d, "units"))
}

#' The rectangle covered by a grid dataset, as a spatstat window (world metres).
eco_grid_window <- function(f, name) {
  d <- f[[name]]
  cell <- h5attr(d, "cell_size_m")
  x0 <- h5attr(d, "origin_x_m")
  y0 <- h5attr(d, "origin_y_m")
  owin(c(x0, x0 + h5attr(d, "width") * cell), c(y0, y0 + h5attr(d, "height") * cell), unitname = c("metre", "metres"))
}

#' A synthesized scene's plants as a marked ppp: marks are the species (factor); the window
#' is the scene's terrain. layer: "undergrowth" or "canopy".
eco_scene_ppp <- function(path, layer = "undergrowth") {
  f <- eco_open(path, "eco-scene")
  on.exit(f$close_all())
  p <- eco_plants(f, layer)
  ppp(p$x, p$y, window = eco_grid_window(f, "terrain/elevation"), marks = p$species)
}

#' A simulation snapshot's undergrowth as a marked ppp (marks: species) in the simulated
#' area (root attributes x0, y0, x1, y1). year: a snapshot year; NULL for the last one.
eco_simulation_ppp <- function(path, year = NULL) {
  f <- eco_open(path, "eco-simulation")
  on.exit(f$close_all())
  groups <- names(f[["snapshots"]])
  years <- as.integer(sub("year_", "", groups))
  if (is.null(year)) year <- max(years)
  if (!(year %in% years)) stop(paste0(path, ": no snapshot of year ", year, " (snapshots: ",
                                      paste(sort(years), collapse = ", "), ")"), call. = FALSE)
  p <- eco_plants(f, paste0("snapshots/", groups[years == year]))
  win <- owin(c(h5attr(f, "x0"), h5attr(f, "x1")), c(h5attr(f, "y0"), h5attr(f, "y1")), unitname = c("metre", "metres"))
  ppp(p$x, p$y, window = win, marks = p$species)
}
