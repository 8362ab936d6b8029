MODULE Polish(SYSMODULE)
    ! Written on the FlexPendant: one robtarget a line, no spaces after commas.
    PERS tooldata tPad:=[TRUE,[[0,0,180.5],[1,0,0,0]],[1.2,[0,0,75],[1,0,0,0],0,0,0]];
    TASK PERS wobjdata wTable:=[FALSE,TRUE,"",[[600,-200,150],[0.707106781,0,0,0.707106781]],[[0,0,0],[1,0,0,0]]];
    CONST robtarget pStart:=[[0,0,30],[0,1,0,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    CONST robtarget pMid:=[[100,0,30],[0,1,0,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    CONST robtarget pEnd:=[[200,0,30],[0,1,0,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    CONST jointtarget jHome:=[[0,0,0,0,30,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];

    PROC main()
        MoveAbsJ jHome,v200,fine,tool0;
        MoveJ Offs(pStart,0,0,50),v200,z20,tPad\WObj:=wTable;
        MoveL pStart,v20,fine,tPad\WObj:=wTable;
        MoveL pMid,v50,z5,tPad\WObj:=wTable;
        MoveL pEnd,v50,fine,tPad\WObj:=wTable;
        MoveL Offs(pEnd,0,0,50),v200,z20,tPad\WObj:=wTable;
        MoveAbsJ jHome,v200,fine,tool0;
    ENDPROC
ENDMODULE
