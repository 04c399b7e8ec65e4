"""The bend - measure - compare loop: settings, states, history, scanners, the cycle state machine, the demo."""
