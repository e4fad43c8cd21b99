"""The track model: columns and canonical fixes, the local frame, preprocessing, summaries."""
