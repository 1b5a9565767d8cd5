"""Dataset converters: recorded multi-camera datasets -> runnable sites."""
