# Helpers shared by the rules.
import anigs

ANIGS_VERSION = anigs.__version__
RESULTS = config.get("results", "results")


def final_targets():
    return []
