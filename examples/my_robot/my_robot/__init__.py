"""My robot for ros_hrc: a planner, a selector and a study policy (docs/extending.md)."""
