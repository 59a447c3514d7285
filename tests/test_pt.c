/* test_pt.c - placeholder */
int main(void) { return 0; }
