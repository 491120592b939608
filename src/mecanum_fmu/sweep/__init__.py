"""Many runs of one scenario on a Dask cluster: the sweep file, workers, results, plots."""
