"""A force outside the library: the neural rate, the sparse regression and the closed forms' search."""
