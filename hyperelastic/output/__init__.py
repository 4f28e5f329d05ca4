"""Layer 7, output: what a run leaves and how it is read back — the HDF5/XDMF writer with checkpoints (writer.py),
the fields a frame holds (fields.py), the quantities a study or a report watches (watch.py), `hyperelastic report`
(report.py), pictures of a frame (plot.py, figures.py)."""
