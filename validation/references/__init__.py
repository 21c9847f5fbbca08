"""References: independent implementations and the accuracy suite, imported by the scripts."""
