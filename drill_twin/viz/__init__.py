"""Looking at results: figures, the rerun layout and viewer, the live view, the console."""
