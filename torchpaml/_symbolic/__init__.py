"""Symbolic forms of a physics: its rates and output as sympy expressions (a run under a dispatch mode that applies
each ATen operation to sympy arrays), and the C compiler that turns printed expressions into shared libraries."""
