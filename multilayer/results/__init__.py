"""A results folder: writing it, reading it back, and the figures of one run."""
