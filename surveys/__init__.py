"""Survey files and the bundled demo run, installed with the package (``station demo``)."""
