"""selector:=my_selector: win-stay, lose-shift over the library's policies."""
from ros_hrc.agents.selectors import Selector


class WinStaySelector(Selector):
    """Keeps the policy while its tasks end with a positive utility; after a loss, the
    library's next policy. The first is drawn from the selector's stream."""

    def __init__(self, policies, rng):
        self.policies = tuple(policies)
        self.current = int(rng.integers(len(self.policies)))

    def choose(self):
        return self.policies[self.current]

    def observe(self, result):
        if result.utility > 0:
            self.note = ""
            return
        self.current = (self.policies.index(result.policy) + 1) % len(self.policies)
        self.note = f"{result.policy} lost (utility {result.utility:.2f}): shift"
