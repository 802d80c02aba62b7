"""File in, files out: what each command runs.  The only layer (with ``cli``) that uses ``io``."""
