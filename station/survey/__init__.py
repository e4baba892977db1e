"""From the surveyor's readings to the track: GSI and coordinate readers, polar reduction,
loading a survey file, and the smoothed profile h(x) with its photocells. Pure but for reading
the survey's own files."""
