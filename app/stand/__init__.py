"""The stand as runs know it between runs: its stored response (response.py)."""
