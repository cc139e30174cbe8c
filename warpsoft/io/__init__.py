"""Running scenes and writing what they did: runner (scene files, parameters), report (JSON),
usd (animations), cli (the `warpsoft` command)."""
