// expect-error: 5:3: break 2 is not inside 2 loops
surface err_break()
{
	while (1) {
		break 2;
	}
}
