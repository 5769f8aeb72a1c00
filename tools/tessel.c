#include "tessel.h"
#include <stdio.h>
int main(void) { printf("tessel %s\n", tessel_version()); return 0; }
