"""The GRAD algorithm: REMA, features, offset, time classifier, recovery, GRU, the Detector.

Imports only the ground modules and ``_tracks``."""
