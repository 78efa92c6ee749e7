"""tfcontact.timefreezing"""
