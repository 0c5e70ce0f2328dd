"""Report figures of the friction law, the stability map and the simulated responses."""
