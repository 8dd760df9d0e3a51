"""Which library effect is missing: the ranking of candidate effects and the ladder of rungs."""
