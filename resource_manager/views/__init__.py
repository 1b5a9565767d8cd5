"""Views: every camera's blobs at the fusion instant in world terms, and which cameras can see now."""
