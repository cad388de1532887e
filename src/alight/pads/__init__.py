"""pads"""
