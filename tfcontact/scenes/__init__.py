"""tfcontact.scenes"""
