"""Reading and writing tracks: CSV/Parquet tables, GPX, NMEA, ROS bags."""
