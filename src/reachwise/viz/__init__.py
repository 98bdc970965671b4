"""The browser viewer (viser): robots, scenarios, results and live runs."""
