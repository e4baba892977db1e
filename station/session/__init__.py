"""A test day: the station config, the raw log written before anything parses a byte, the
processor (bytes -> descents), fits of finished descents with the day's annotations, the results
CSV, the session folder, the serial port, and the one acquisition loop that record, live, demo
and replay share."""
