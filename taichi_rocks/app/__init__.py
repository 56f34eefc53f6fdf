"""What the commands orchestrate, over every room's public face."""
