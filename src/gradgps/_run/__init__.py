"""Running detectors over files and streams: chunked CSV, follow mode, Dask and Redis fleets, reports."""
