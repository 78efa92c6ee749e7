"""tfcontact.viz"""
