"""The seed task's whole loop without ROS (local_loop.py): a seeded run repeats step for step,
through episode resets, and another seed is another run. (That the launched stack's seeded
run is its recorded one: test/rostest/test_hrc.py.)"""
from local_loop import LocalLoop, record


def seeded_run(seed: int) -> list:
    loop = LocalLoop("seed", "distracted", "robot", seed=seed, max_steps=6, max_trials=100)
    try:
        return [record(report) for report in loop.run(14)]
    finally:
        loop.close()


def test_the_same_seed_gives_the_same_steps_and_another_seed_others():
    first = seeded_run(11)
    assert len(first) == 14 and len({step[0] for step in first}) >= 2, "no episode reset"
    assert seeded_run(11) == first
    assert len({step[2] for step in first}) > 1, "the human did just one thing"
    assert seeded_run(12) != first
