"""The fluid contract: what a coupler asks of a fluid."""
