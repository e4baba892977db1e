"""Text for people: one-line descent summaries and tables shared by the CLI and the UI."""
