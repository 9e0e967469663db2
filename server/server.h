/* ftm-server's whole program behind one call, so that a test can run it
 * more than once in a process (tests/fuzz/fuzz_session.c) and main.c stays
 * a line long. */
#ifndef FTM_SERVER_H
#define FTM_SERVER_H

/* Runs ftm-server with these arguments (argv[0] the program name) and
 * returns its exit status: 0 success, 1 a replay or input run that failed
 * its check, 2 bad options, 3 a resource or start-up error. --help prints
 * the usage and exits the process. */
int ftm_server_main(int argc, char **argv);

#endif
