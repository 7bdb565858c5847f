"""HandSplice browser app (Panel). Thin front over ``engine``: no algorithm code here."""
