"""The benchmark contract: each measured benchmark's protocol as one frozen value, their registry, and the
leaderboard's result fields."""
